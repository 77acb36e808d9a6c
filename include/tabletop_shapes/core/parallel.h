// Independent work items (one per object cluster) spread over the machine's cores.
#pragma once

#include <cstddef>
#include <functional>

namespace tabletop_shapes {

// Calls body(i) for every i in [0, n), on up to `threads` threads (0: workerThreads()), the
// calling thread included; items are taken in order, so when the largest come first the load
// evens out. Returns when all are done; an exception thrown by body is rethrown here (the
// first one; the other items still run).
void parallelFor(size_t n, const std::function<void(size_t)>& body, unsigned threads = 0);

// Helper threads parallelFor started so far in this process. Its helpers are kept between calls
// (a pool): a call while the pool serves another (from within an item, or from another thread)
// starts threads of its own.
size_t parallelThreadsStarted();

// The thread count parallelFor uses when given 0: the last setWorkerThreads(n > 0), else the
// environment variable TABLETOP_SHAPES_THREADS (a positive number), else one per core. The
// results must not depend on it; tests and tools set it to show that they do not.
unsigned workerThreads();
void setWorkerThreads(unsigned threads);  // 0: back to the environment / one per core

// The threads for parallel work started from the calling thread: 1 on a thread that parallelFor
// runs items on (with more than one thread: its items keep the cores busy already), else
// workerThreads(). A single item (one object on the table) then still gets every core.
unsigned freeWorkerThreads();

}  // namespace tabletop_shapes
