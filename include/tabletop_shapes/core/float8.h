// Eight floats at once with GCC's vector extension where the CPU has AVX2 (x86-64, GCC): the
// types and lane operations the eight-lane point tests share (plane_support, round_lid,
// convex_polygon), beside float4.h's four-lane ones. Each lane does the float operations of the
// scalar code. The functions are AVX2 code: call them from AVX2 functions (target("avx2"), run
// after cpuHasAvx2()) and from always-inlined ones inlined there.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__)
#define TABLETOP_SHAPES_EIGHT_LANES 1

#include <immintrin.h>

// Lanes of eight floats are passed only within AVX2 functions and always-inlined ones: GCC's note
// that passing them without AVX changes the ABI does not apply (in the files including this).
#pragma GCC diagnostic ignored "-Wpsabi"

namespace tabletop_shapes {

using Float8 = float __attribute__((vector_size(32)));
using Int8 = int __attribute__((vector_size(32)));

// Bit i set where lane i of the comparison result `mask` is true (-1).
__attribute__((target("avx2"))) inline unsigned lanesOf(Int8 mask) {
  return static_cast<unsigned>(_mm256_movemask_ps((__m256)mask));
}

__attribute__((target("avx2"))) inline Float8 squareRoot(Float8 value) {
  return (Float8)_mm256_sqrt_ps((__m256)value);  // correctly rounded, as std::sqrt
}

}  // namespace tabletop_shapes

#endif
