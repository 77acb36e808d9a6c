#include "tabletop_shapes/core/table_edge.h"

#include "tabletop_shapes/core/convex_polygon.h"
#include "tabletop_shapes/core/parallel.h"

#include <cstdio>
#include <limits>

namespace tabletop_shapes {
namespace {

// Standard deviations of depth noise by which a point must stand beyond the hull's edge band to
// stand over the table (as the table stage's kBelowNoiseSigmas).
constexpr float kEdgeNoiseSigmas = 4.0f;
// A point this far outside the hull is outside it; nearer, it lies on the hull's edge (the hull's
// vertices are table inliers, and those above table.min_height are object points too) [m].
constexpr float kOnTheEdge = 0.001f;
// An object standing on the table has this share of its points at least beyond the edge band
// (its front, seen from the camera; 20-100 % on the rendered everyday scenes). Noise and edge
// bleeding carry a few of a wall's points past the band's 4 sigma: 1 of 2171 up to 341 of
// 50645 or 7 of 190 (at most 3.7 %) on the rendered RealSense walls; one such point kept a
// wall slab as an object.
constexpr float kMinShareBeyondTheBand = 0.1f;

// True when the camera does not see `foot` (optical frame): it lies beyond the image's border.
bool footOutOfView(const Eigen::Vector3f& foot, const ViewBounds& view) {
  if (!view.known) return false;
  if (!(foot.z() > 0.0f)) return true;
  const float tan_x = foot.x() / foot.z(), tan_y = foot.y() / foot.z();
  return tan_x < view.min_tan_x || tan_x > view.max_tan_x || tan_y < view.min_tan_y ||
         tan_y > view.max_tan_y;
}

}  // namespace

std::string whyNotOnTheTable(const Cloud& cluster, const Plane& table,
                             const std::vector<Eigen::Vector3f>& hull,
                             float depth_noise_at_one_metre, float hull_margin,
                             const Eigen::Vector3f& eye, const ViewBounds* view) {
  if (hull.size() < 3 || cluster.empty()) return "";
  // The hull in the plane's coordinates, as the table stage builds it.
  const Eigen::Vector3f u = table.normal.unitOrthogonal(), v = table.normal.cross(u);
  std::vector<Eigen::Vector2f> hull_2d;
  hull_2d.reserve(hull.size());
  for (const Eigen::Vector3f& corner : hull) hull_2d.emplace_back(u.dot(corner), v.dot(corner));
  hull_2d = convexHull2d(std::move(hull_2d));  // counter-clockwise whatever the input's order
  if (hull_2d.size() < 3) return "";
  const float eye_height = table.signedDistance(eye);
  auto insideHull = [&](const Eigen::Vector3f& p) {
    return insideDistance(hull_2d, Eigen::Vector2f(u.dot(p), v.dot(p)));
  };
  float deepest = -std::numeric_limits<float>::max(), deepest_band = 0.0f, deepest_range = 0.0f;
  size_t beyond_the_band = 0;
  // Stands on the table once enough of its points stand beyond the band: the count only grows,
  // so the rest of the points cannot change the answer (most clusters stop after ~10 %).
  auto standsOnTheTable = [&]() {
    return beyond_the_band >= kMinShareBeyondTheBand * cluster.size();
  };
  for (const Point& point : cluster.points) {
    const Eigen::Vector3f p = point.getVector3fMap();
    const float inside = insideHull(p);
    const float range = (p - eye).norm();
    const float band = hull_margin + kEdgeNoiseSigmas * depth_noise_at_one_metre * range * range;
    const float height = table.signedDistance(p);
    if (inside < -kOnTheEdge) {
      // Outside the hull: the table stage took it standing on the table beyond the image's
      // border (the hull ends at the border there: the cluster is cut by it, not at the table's
      // edge) or over the table hidden beyond the hull. The latter stands on the table when it
      // lies further out than the depth noise carries a wall's points past the hull's edge
      // (the wall's foot is that edge; hull_margin is for the table's own ragged edge inside).
      if (!view || footOutOfView(p - height * table.normal, *view)) return "";
      if (-inside >= band - hull_margin) {
        ++beyond_the_band;
        if (standsOnTheTable()) return "";
      } else if (inside - band > deepest - deepest_band) {
        deepest = inside, deepest_band = band, deepest_range = range;
      }
      continue;
    }
    // Where its line of sight meets the table: the point hides the table there.
    const float hidden = height < eye_height
                             ? insideHull(eye + (p - eye) * (eye_height / (eye_height - height)))
                             : -std::numeric_limits<float>::max();
    // Standing on the table beyond the image (as the table stage keeps points outside the
    // hull): the camera sees the table behind it, not past the hull's edge, and its foot is
    // out of view.
    if (view && hidden >= -kOnTheEdge && footOutOfView(p - height * table.normal, *view)) {
      return "";
    }
    const float deeper = std::max(inside, hidden);
    if (deeper >= band) {
      ++beyond_the_band;
      if (standsOnTheTable()) return "";
    } else if (deeper - band > deepest - deepest_band) {
      deepest = deeper, deepest_band = band, deepest_range = range;
    }
  }
  if (standsOnTheTable()) return "";
  char reason[480];
  const int length = std::snprintf(
      reason, sizeof reason,
      "not on the table: rises along the edge of the table's hull (a wall's foot behind the "
      "table): its points stand, and hide the table, at most %.3f m inside the hull, within the "
      "edge band of %.3f m (table.hull_margin %.3f m + %.0f x the depth noise %.4f m at %.2f m)",
      deepest, deepest_band, hull_margin, kEdgeNoiseSigmas,
      depth_noise_at_one_metre * deepest_range * deepest_range, deepest_range);
  if (beyond_the_band > 0 && length > 0 && length < static_cast<int>(sizeof reason)) {
    std::snprintf(reason + length, sizeof reason - length,
                  ", but for %zu of its %zu points (under %.0f %%: noise and edge bleeding)",
                  beyond_the_band, cluster.size(), 100.0f * kMinShareBeyondTheBand);
  }
  return reason;
}

void rejectClustersOffTheTable(std::vector<CloudPtr>& clusters, const Plane& table,
                               const std::vector<Eigen::Vector3f>& hull,
                               float depth_noise_at_one_metre, float hull_margin,
                               const Eigen::Vector3f& eye, const ViewBounds* view,
                               std::vector<RejectedCluster>& rejected) {
  // Each cluster on its own (one per core), kept or rejected in the clusters' order.
  std::vector<std::string> reasons(clusters.size());
  parallelFor(clusters.size(), [&](size_t c) {
    reasons[c] = whyNotOnTheTable(*clusters[c], table, hull, depth_noise_at_one_metre, hull_margin,
                                  eye, view);
  });
  std::vector<CloudPtr> kept;
  kept.reserve(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    if (reasons[c].empty()) {
      kept.push_back(std::move(clusters[c]));
    } else {
      rejected.push_back({std::move(clusters[c]), std::move(reasons[c])});
    }
  }
  clusters.swap(kept);
}

}  // namespace tabletop_shapes
