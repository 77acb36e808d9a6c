// Four floats at once with GCC's vector extension (SSE on x86): the types and the few lane
// operations the vectorised point tests share (plane_support, round_lid). Each lane does the
// float operations of the scalar code, so the results are the same to the bit.
#pragma once

#include <cmath>

#ifdef __SSE__
#include <xmmintrin.h>
#endif

namespace tabletop_shapes {

using Float4 = float __attribute__((vector_size(16)));
using Int4 = int __attribute__((vector_size(16)));
using Double2 = double __attribute__((vector_size(16)));

inline Float4 broadcast(float value) { return Float4{} + value; }
inline Float4 magnitude(Float4 value) { return (Float4)((Int4)value & 0x7fffffff); }

// Bit i set where lane i of the comparison result `mask` is true (-1).
inline unsigned lanesOf(Int4 mask) {
#ifdef __SSE__
  return static_cast<unsigned>(_mm_movemask_ps((__m128)mask));  // the lanes' sign bits
#else
  return (mask[0] & 1u) | (mask[1] & 2u) | (mask[2] & 4u) | (mask[3] & 8u);
#endif
}

inline Float4 squareRoot(Float4 value) {
#ifdef __SSE__
  return (Float4)_mm_sqrt_ps((__m128)value);  // correctly rounded, as std::sqrt
#else
  for (int lane = 0; lane < 4; ++lane) value[lane] = std::sqrt(value[lane]);
  return value;
#endif
}

}  // namespace tabletop_shapes
