// Independent work items (one per object cluster) spread over the machine's cores.
#pragma once

#include <cstddef>
#include <functional>

namespace tabletop_shapes {

// Calls body(i) for every i in [0, n), on up to `threads` threads (0: one per core), the
// calling thread included; items are taken in order, so when the largest come first the load
// evens out. Returns when all are done; an exception thrown by body is rethrown here (the
// first one; the other items still run).
void parallelFor(size_t n, const std::function<void(size_t)>& body, unsigned threads = 0);

}  // namespace tabletop_shapes
