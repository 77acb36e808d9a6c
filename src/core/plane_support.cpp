#include "tabletop_shapes/core/plane_support.h"

#include <algorithm>
#include <cmath>

namespace tabletop_shapes {

namespace {
Float4 broadcast(float value) { return Float4{} + value; }
Float4 magnitude(Float4 value) { return (Float4)((Int4)value & 0x7fffffff); }
// Bit i set where lane i of the comparison result `mask` is true (-1).
unsigned lanesOf(Int4 mask) {
  return (mask[0] & 1u) | (mask[1] & 2u) | (mask[2] & 4u) | (mask[3] & 8u);
}
}  // namespace

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
  for (size_t k = 0; k < inlier_lanes_.size(); ++k) {
    for (unsigned lanes = inlier_lanes_[k]; lanes != 0; lanes &= lanes - 1) {
      const int lane = __builtin_ctz(lanes);
      if (support) support->push_back(indices_[4 * k + lane]);
      if (sum_angles) *angle_sum += std::acos(std::min(cosine_[k][lane], 1.0f));
    }
  }
  return count;
}

}  // namespace tabletop_shapes
