#include "tabletop_shapes/core/plane_support.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace tabletop_shapes {

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

// The inlier test of a plane, four points at a time: distance below the threshold AND |cosine|
// of the point normal above the threshold.
struct PlaneSupport::PlaneTest {
  PlaneTest(const Eigen::Vector3f& normal, float d, float distance_threshold, float cos_threshold)
      : a(broadcast(normal.x())),
        b(broadcast(normal.y())),
        c(broadcast(normal.z())),
        offset(broadcast(d)),
        max_distance(broadcast(distance_threshold)),
        min_cosine(broadcast(cos_threshold)) {}
  // The lanes of block k that are inliers (all bits set) and its |cosines| (`cosine`).
  Int4 inliers(const PlaneSupport& points, size_t k, Float4& cosine) const {
    const Float4 distance = magnitude(
        (a * points.points_.x[k] + (b * points.points_.y[k] + c * points.points_.z[k])) + offset);
    cosine =
        magnitude(a * points.normals_.x[k] + (b * points.normals_.y[k] + c * points.normals_.z[k]));
    // Negated like `if (distance >= threshold) skip`, so that NaN passes alike.
    return ~(distance >= max_distance) & ~(cosine <= min_cosine);
  }
  Float4 a, b, c, offset, max_distance, min_cosine;
};

int PlaneSupport::collect(const Eigen::Vector3f& normal, float d, float distance_threshold,
                          float cos_threshold, std::vector<int>* support, double* angle_sum,
                          int min_count) {
  const PlaneTest test(normal, d, distance_threshold, cos_threshold);
  Int4 counts = {};
  for (size_t k = 0; k < points_.x.size(); ++k) {
    const Int4 inlier = test.inliers(*this, k, cosine_[k]);
    inlier_lanes_[k] = lanesOf(inlier);
    counts -= inlier;
  }
  const int count = counts[0] + counts[1] + counts[2] + counts[3];
  if (support) {
    for (size_t k = 0; k < inlier_lanes_.size(); ++k) {
      for (unsigned lanes = inlier_lanes_[k]; lanes != 0; lanes &= lanes - 1) {
        support->push_back(indices_[4 * k + __builtin_ctz(lanes)]);
      }
    }
  }
  if (angle_sum && count >= min_count) *angle_sum += sumOfInlierAngles();
  return count;
}

int PlaneSupport::countWithAngleBound(const Eigen::Vector3f& normal, float d,
                                      float distance_threshold, float cos_threshold,
                                      double& angle_bound) {
  const PlaneTest test(normal, d, distance_threshold, cos_threshold);
  const Float4 one = broadcast(1.0f);
  Int4 counts = {};
  Float4 bounds = {};
  for (size_t k = 0; k < points_.x.size(); ++k) {
    Float4 cosine;
    const Int4 inlier = test.inliers(*this, k, cosine);
    counts -= inlier;
    // 1 - c is exact for c in [0.5, 1] (the inliers' cosines; a NaN stays NaN).
    const Float4 clamped = one < cosine ? one : cosine;
    bounds += (Float4)((Int4)squareRoot((one - clamped) * 2.0f) & inlier);
  }
  // Each root within half an ulp, acosf within one, the lanes' float sums within one ulp per
  // term: a relative margin of 2^-22 per block and a few more keeps the bound below the sum.
  const double margin = 1.0 - std::ldexp(static_cast<double>(points_.x.size() + 4), -22);
  angle_bound = margin * ((static_cast<double>(bounds[0]) + static_cast<double>(bounds[1])) +
                          (static_cast<double>(bounds[2]) + static_cast<double>(bounds[3])));
  return counts[0] + counts[1] + counts[2] + counts[3];
}

double PlaneSupport::sumOfInlierAngles() const {
  // Each angle is a float: 0 or at least acos(1 - 2^-24) > 2^-12, so a multiple of 2^-35, and
  // at most pi < 4. Their sum is exact in a double (53 bits) below 2^18, i.e. for up to 2^16
  // points, and then the same in any order; beyond, it is summed in the points' order.
  const bool exact_in_any_order = 4 * inlier_lanes_.size() <= (1u << 16);
  const Float4 one = broadcast(1.0f), half = broadcast(0.5f);
  const Int4 lane_bits = {1, 2, 4, 8};
  Double2 low_lanes = {}, high_lanes = {};
  double sum = 0.0;
  for (size_t k = 0; k < inlier_lanes_.size(); ++k) {
    const unsigned lanes = inlier_lanes_[k];
    if (lanes == 0) continue;
    // std::min(cosine, 1.0f) per lane (NaN stays NaN), and the acos of all four at once where
    // they lie in [0.5, 1); acos(1) = 0 and the rare others one at a time.
    const Float4 cosine = one < cosine_[k] ? one : cosine_[k];
    const Float4 angle = acosOfHalfToOne(cosine);
    if (exact_in_any_order) {
      const Int4 inlier = ((Int4{} + static_cast<int>(lanes)) & lane_bits) != 0;
      const Int4 vector_lanes = inlier & (cosine >= half) & (cosine < one);
      const Float4 kept = (Float4)((Int4)angle & vector_lanes);
      low_lanes += Double2{kept[0], kept[1]};
      high_lanes += Double2{kept[2], kept[3]};
      for (unsigned rest = lanes & ~lanesOf(vector_lanes); rest != 0; rest &= rest - 1) {
        sum += std::acos(cosine[__builtin_ctz(rest)]);  // 0 for a cosine of 1
      }
      continue;
    }
    for (unsigned rest = lanes; rest != 0; rest &= rest - 1) {
      const float c = cosine[__builtin_ctz(rest)];
      sum += c >= 0.5f && c < 1.0f ? angle[__builtin_ctz(rest)] : std::acos(c);
    }
  }
  return sum + ((low_lanes[0] + low_lanes[1]) + (high_lanes[0] + high_lanes[1]));
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
