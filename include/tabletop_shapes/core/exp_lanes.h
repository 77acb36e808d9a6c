// exp of many doubles at once with the very doubles std::exp gives.
#pragma once

#include <cstddef>

namespace tabletop_shapes {

// values[i] = std::exp(values[i]) for i < count, bit for bit. Where glibc's exp is its FMA
// variant (a CPU with AVX2 and FMA, the variant glibc picks there), the same steps run four
// lanes at a time: a few instructions per value instead of a call of ~45. Elsewhere, and for
// arguments beyond its main path's range (|x| < 2^-54 or >= 512, NaN), std::exp itself.
void expInPlace(double* values, size_t count);

// Whether expInPlace runs four lanes at a time on this machine (else one std::exp per value).
bool expInLanes();

}  // namespace tabletop_shapes
