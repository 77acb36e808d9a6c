#include "tabletop_shapes/core/plane_support.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#ifdef __SSE__
#include <xmmintrin.h>
#endif

namespace tabletop_shapes {

namespace {
Float4 broadcast(float value) { return Float4{} + value; }
Float4 magnitude(Float4 value) { return (Float4)((Int4)value & 0x7fffffff); }
// Bit i set where lane i of the comparison result `mask` is true (-1).
unsigned lanesOf(Int4 mask) {
#ifdef __SSE__
  return static_cast<unsigned>(_mm_movemask_ps((__m128)mask));  // the lanes' sign bits
#else
  return (mask[0] & 1u) | (mask[1] & 2u) | (mask[2] & 4u) | (mask[3] & 8u);
#endif
}
Float4 squareRoot(Float4 value) {
#ifdef __SSE__
  return (Float4)_mm_sqrt_ps((__m128)value);  // correctly rounded, as std::sqrt
#else
  for (int lane = 0; lane < 4; ++lane) value[lane] = std::sqrt(value[lane]);
  return value;
#endif
}
}  // namespace

Float4 acosOfHalfToOne(Float4 x) {
  // fdlibm's e_acosf.c, branch x >= 0.5: acos(x) = 2 asin(sqrt((1 - x) / 2)), the asin from a
  // rational approximation and a split of the root into a high part and a correction.
  constexpr float kP0 = 1.6666667163e-01f, kP1 = -3.2556581497e-01f, kP2 = 2.0121252537e-01f,
                  kP3 = -4.0055535734e-02f, kP4 = 7.9153501429e-04f, kP5 = 3.4793309169e-05f;
  constexpr float kQ1 = -2.4033949375e+00f, kQ2 = 2.0209457874e+00f, kQ3 = -6.8828397989e-01f,
                  kQ4 = 7.7038154006e-02f;
  const Float4 z = (1.0f - x) * 0.5f;
  const Float4 s = squareRoot(z);
  const Float4 high = (Float4)((Int4)s & static_cast<int>(0xfffff000u));
  const Float4 correction = (z - high * high) / (s + high);
  const Float4 p = z * (kP0 + z * (kP1 + z * (kP2 + z * (kP3 + z * (kP4 + z * kP5)))));
  const Float4 q = 1.0f + z * (kQ1 + z * (kQ2 + z * (kQ3 + z * kQ4)));
  const Float4 w = (p / q) * s + correction;
  return 2.0f * (high + w);
}

void VectorBlocks::resize(size_t points, float padding) {
  const size_t blocks = (points + 3) / 4;
  for (auto* column : {&x, &y, &z}) column->assign(blocks, broadcast(padding));
}

PlaneSupport::PlaneSupport(const NormalCloud& cloud, const std::vector<int>& indices)
    : indices_(indices) {
  points_.resize(indices.size(), kFarAway);
  normals_.resize(indices.size(), 0.0f);
  for (size_t k = 0; k < indices.size(); ++k) {
    const auto& p = cloud[indices[k]];
    points_.set(k, p.x, p.y, p.z);
    normals_.set(k, p.normal_x, p.normal_y, p.normal_z);
  }
  inlier_lanes_.resize(points_.x.size());
  cosine_.resize(points_.x.size());
}

int PlaneSupport::collect(const Eigen::Vector3f& normal, float d, float distance_threshold,
                          float cos_threshold, std::vector<int>* support, double* angle_sum,
                          int min_count) {
  const Float4 a = broadcast(normal.x()), b = broadcast(normal.y()), c = broadcast(normal.z());
  const Float4 offset = broadcast(d);
  const Float4 max_distance = broadcast(distance_threshold);
  const Float4 min_cosine = broadcast(cos_threshold);
  Int4 counts = {};
  for (size_t k = 0; k < points_.x.size(); ++k) {
    const Float4 distance =
        magnitude((a * points_.x[k] + (b * points_.y[k] + c * points_.z[k])) + offset);
    const Float4 cosine = magnitude(a * normals_.x[k] + (b * normals_.y[k] + c * normals_.z[k]));
    // Negated like `if (distance >= threshold) skip`, so that NaN passes alike.
    const Int4 inlier = ~(distance >= max_distance) & ~(cosine <= min_cosine);
    inlier_lanes_[k] = lanesOf(inlier);
    cosine_[k] = cosine;
    counts -= inlier;
  }
  const int count = counts[0] + counts[1] + counts[2] + counts[3];
  const bool sum_angles = angle_sum && count >= min_count;
  if (!support && !sum_angles) return count;
  const Float4 one = broadcast(1.0f);
  for (size_t k = 0; k < inlier_lanes_.size(); ++k) {
    if (inlier_lanes_[k] == 0) continue;
    // std::min(cosine, 1.0f) per lane (NaN stays NaN), and the acos of all four at once where
    // they lie in [0.5, 1); acos(1) = 0 and the rare others one at a time.
    const Float4 cosine = one < cosine_[k] ? one : cosine_[k];
    const Float4 angle = sum_angles ? acosOfHalfToOne(cosine) : Float4{};
    for (unsigned lanes = inlier_lanes_[k]; lanes != 0; lanes &= lanes - 1) {
      const int lane = __builtin_ctz(lanes);
      if (support) support->push_back(indices_[4 * k + lane]);
      if (sum_angles) {
        const float c = cosine[lane];
        *angle_sum += c >= 0.5f && c < 1.0f ? angle[lane] : std::acos(c);
      }
    }
  }
  return count;
}

PointsNearPlane::PointsNearPlane(const Cloud& cloud, const std::vector<int>& indices)
    : indices_(indices) {
  points_.resize(indices.size(), std::numeric_limits<float>::quiet_NaN());  // never within
  for (size_t k = 0; k < indices.size(); ++k) {
    const Point& p = cloud[indices[k]];
    points_.set(k, p.x, p.y, p.z);
  }
  indices_.resize(4 * points_.x.size(), -1);  // the padding's, never collected
}

void PointsNearPlane::collect(const Plane& plane, float threshold, std::vector<int>& within) const {
  const Float4 a = broadcast(plane.normal.x()), b = broadcast(plane.normal.y()),
               c = broadcast(plane.normal.z()), offset = broadcast(plane.d);
  const Float4 max_distance = broadcast(threshold);
  // Written into a buffer kept from call to call (no clearing), without a branch per point:
  // every index of a partly kept block is written, the count advanced past the kept ones.
  thread_local std::vector<int> kept;
  if (kept.size() < indices_.size()) kept.resize(indices_.size());
  int* out = kept.data();
  const int* index = indices_.data();
  size_t count = 0;
  for (size_t k = 0; k < points_.x.size(); ++k, index += 4) {
    const Float4 distance = (a * points_.x[k] + (b * points_.y[k] + c * points_.z[k])) + offset;
    const unsigned lanes = lanesOf(magnitude(distance) <= max_distance);
    if (lanes == 0) continue;
    if (lanes == 15) {  // runs of whole blocks on a plane's surface
      std::memcpy(out + count, index, 4 * sizeof(int));
      count += 4;
      continue;
    }
    for (int lane = 0; lane < 4; ++lane) {
      out[count] = index[lane];
      count += (lanes >> lane) & 1u;
    }
  }
  within.assign(out, out + count);
}

}  // namespace tabletop_shapes
