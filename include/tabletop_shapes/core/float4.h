// Four floats at once with GCC's vector extension (SSE on x86): the types and the few lane
// operations the vectorised point tests share (plane_support, round_lid, preprocess,
// table_segmentation). Each lane does the
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

#ifdef __SSE__
// x, y and z of four PCL points (each starts with x y z and a fourth float) as lanes: the loads
// and the transpose the point passes share (preprocess, table_segmentation).
template <typename PointT>
inline void coordinatesOfFour(const PointT& p0, const PointT& p1, const PointT& p2,
                              const PointT& p3, Float4& x, Float4& y, Float4& z) {
  __m128 a = _mm_loadu_ps(&p0.x), b = _mm_loadu_ps(&p1.x), c = _mm_loadu_ps(&p2.x),
         w = _mm_loadu_ps(&p3.x);
  _MM_TRANSPOSE4_PS(a, b, c, w);
  x = (Float4)a, y = (Float4)b, z = (Float4)c;
}

// The same for four consecutive points.
template <typename PointT>
inline void coordinatesOfFour(const PointT* points, Float4& x, Float4& y, Float4& z) {
  coordinatesOfFour(points[0], points[1], points[2], points[3], x, y, z);
}

// The same for the points indices[0 .. 3] of `points`.
template <typename PointT>
inline void coordinatesOfFour(const PointT* points, const int* indices, Float4& x, Float4& y,
                              Float4& z) {
  coordinatesOfFour(points[indices[0]], points[indices[1]], points[indices[2]], points[indices[3]],
                    x, y, z);
}
#endif

inline Float4 squareRoot(Float4 value) {
#ifdef __SSE__
  return (Float4)_mm_sqrt_ps((__m128)value);  // correctly rounded, as std::sqrt
#else
  for (int lane = 0; lane < 4; ++lane) value[lane] = std::sqrt(value[lane]);
  return value;
#endif
}

}  // namespace tabletop_shapes
