// The plane each object rests on: see support.h.
#include "tabletop_shapes/core/support.h"

#include "tabletop_shapes/core/convex_polygon.h"

#include <algorithm>

namespace tabletop_shapes {
namespace {

// A cluster whose bottom lies this far above the table may rest on another object [m]: more
// than the table's noise band (table.min_height 8 mm) and the voxel grid.
constexpr float kMinLift = 0.03f;
// The bottom is the height below which this share of the cluster's points lie: a few stray
// points of the object beneath do not set it. Small, because the split gives the lowest rows of
// an object lying on another to the one beneath (at the concave seam): a box lying across two
// (test_support) kept 1/20 of its lowest 1 cm, and 3 % put its bottom 9 mm high.
constexpr float kBottomQuantile = 0.01f;
// The object beneath reaches up to the bottom: its top lies within this below it or above
// it (an object lying across a lower one's edge dips into its top face's noise) [m].
constexpr float kTopBelowBottom = 0.03f;
constexpr float kTopAboveBottom = 0.02f;
// The object lies over the footprints of the objects beneath: this share of its points, seen
// from above, within kFootprintReach of them. A box lying across a thin standing one overhangs
// it (learn24: an eighth over it); an object whose lower part is hidden behind one in front is
// seen behind that one's footprint, not over it.
constexpr float kMinSupportedShare = 0.1f;
// Noise blurs the footprints' edges; an upper box flush with the lower one's front has its front
// face on the footprint's edge [m].
constexpr float kFootprintReach = 0.01f;

struct Extent {
  float bottom = 0.0f, top = 0.0f;
  std::vector<Eigen::Vector2f> footprint;  // convex hull on the table, (u, v)
  std::vector<Eigen::Vector2f> projected;  // the points on the table, (u, v)
};

}  // namespace

std::vector<Plane> supportPlanes(const std::vector<CloudPtr>& clusters, const Plane& table) {
  const Eigen::Vector3f u = table.normal.unitOrthogonal(), v = table.normal.cross(u);
  std::vector<Extent> extents(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    const Cloud& cluster = *clusters[c];
    if (cluster.empty()) continue;
    std::vector<float> heights;
    std::vector<Eigen::Vector2f> projected;
    heights.reserve(cluster.size());
    projected.reserve(cluster.size());
    for (const auto& point : cluster) {
      const Eigen::Vector3f p = point.getVector3fMap();
      heights.push_back(table.signedDistance(p));
      projected.emplace_back(u.dot(p), v.dot(p));
    }
    Extent& e = extents[c];
    e.top = *std::max_element(heights.begin(), heights.end());
    std::vector<float> sorted = heights;
    const size_t k = static_cast<size_t>(kBottomQuantile * static_cast<float>(sorted.size()));
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    e.bottom = sorted[k];
    e.footprint = convexHull2d(projected);
    e.projected = std::move(projected);
  }

  std::vector<Plane> planes(clusters.size(), table);
  for (size_t c = 0; c < clusters.size(); ++c) {
    const Extent& upper = extents[c];
    if (!(upper.bottom > kMinLift) || upper.projected.empty()) continue;
    size_t supported = 0;
    for (const Eigen::Vector2f& q : upper.projected) {
      for (size_t d = 0; d < clusters.size(); ++d) {
        const Extent& lower = extents[d];
        if (d == c || lower.top < upper.bottom - kTopBelowBottom ||
            lower.top > upper.bottom + kTopAboveBottom || lower.footprint.size() < 3) {
          continue;
        }
        if (insideDistance(lower.footprint, q) > -kFootprintReach) {
          ++supported;
          break;
        }
      }
    }
    if (supported >= kMinSupportedShare * static_cast<float>(upper.projected.size())) {
      planes[c].d -= upper.bottom;  // the table's plane lifted to the cluster's bottom
    }
  }
  return planes;
}

}  // namespace tabletop_shapes
