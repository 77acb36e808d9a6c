#include "tabletop_shapes/core/slab_nearest.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace tabletop_shapes {

SlabNearest::SlabNearest(const Cloud& cloud) {
  order_.resize(cloud.size());
  std::iota(order_.begin(), order_.end(), 0);
  std::sort(order_.begin(), order_.end(), [&cloud](int a, int b) {
    return cloud[a].x < cloud[b].x || (cloud[a].x == cloud[b].x && a < b);
  });
  sorted_x_.reserve(order_.size());
  // Padding far from every query: its squared distance overflows to infinity, above any bound.
  blocks_.resize(order_.size(), 1e30f);
  for (size_t k = 0; k < order_.size(); ++k) {
    const auto& p = cloud[order_[k]];
    sorted_x_.push_back(p.x);
    blocks_.set(k, p.x, p.y, p.z);
  }
}

bool SlabNearest::nearest(const Eigen::Vector3f& query, float bound, Hit& hit) const {
  if (!(bound >= 0.0f)) return false;
  // Every point within the bound has |x - query x| <= sqrt(bound); the slack covers the float
  // rounding of the distances.
  const float reach = std::sqrt(bound) * 1.001f + 1e-6f;
  const size_t low =
      std::lower_bound(sorted_x_.begin(), sorted_x_.end(), query.x() - reach) - sorted_x_.begin();
  const size_t high =
      std::upper_bound(sorted_x_.begin(), sorted_x_.end(), query.x() + reach) - sorted_x_.begin();
  if (low >= high) return false;
  const Float4 qx = Float4{} + query.x(), qy = Float4{} + query.y(), qz = Float4{} + query.z();
  // Whole blocks: points beside the slab in them are further than the bound, or real
  // candidates all the same.
  const size_t first = low / 4, last = (high + 3) / 4;
  auto squaredAt = [&](size_t k) {
    const Float4 dx = qx - blocks_.x[k], dy = qy - blocks_.y[k], dz = qz - blocks_.z[k];
    return (dx * dx + dy * dy) + dz * dz;
  };
  Float4 least = Float4{} + std::numeric_limits<float>::infinity();
  for (size_t k = first; k < last; ++k) {
    const Float4 squared = squaredAt(k);
    least = squared < least ? squared : least;
  }
  const float smallest = std::min(std::min(least[0], least[1]), std::min(least[2], least[3]));
  if (!(smallest <= bound)) return false;
  int count = 0, index = std::numeric_limits<int>::max();
  const Float4 wanted = Float4{} + smallest;
  for (size_t k = first; k < last; ++k) {
    const Int4 equal = squaredAt(k) == wanted;
    if (!(equal[0] | equal[1] | equal[2] | equal[3])) continue;
    for (int lane = 0; lane < 4; ++lane) {
      if (equal[lane]) {
        ++count;
        index = std::min(index, order_[4 * k + lane]);
      }
    }
  }
  hit.squared = smallest;
  hit.index = index;
  hit.tied = count > 1;
  return true;
}

}  // namespace tabletop_shapes
