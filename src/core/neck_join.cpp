// Joining a bottle's neck to its body again: see neck_join.h.
#include "tabletop_shapes/core/neck_join.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

namespace tabletop_shapes {
namespace {

// A bottle's neck (with its cap) meets the shoulder at a concave seam: the split
// (splitAtConcaveSeams) cuts it off and supportPlanes stands it on the shoulder, a round solid
// of its own (on rendered RealSense scenes, 15 of 40 such necks, r 1.7-2.3 cm, h 4-6 cm, and
// their bottles 4-6 cm short). A solid standing on a wider round one, on its axis (within
// kNeckAxisOffset of the lower one's radius) and starting within kNeckGap of its top, is that
// neck: the two clusters are one object again, fitted as one on the lower one's support. A box
// below (a can standing on a box) keeps them apart.
constexpr float kNeckAxisOffset = 0.5f;
constexpr float kNeckGap = 0.03f;  // [m]
// An object rests on another when its bottom lies this far above the table [m].
constexpr float kNeckLift = 0.01f;

bool isRound(const ShapeFit& fit) {
  return fit.ok && (fit.type == ShapeType::Cylinder || fit.type == ShapeType::Cone);
}
// Half the widest horizontal extent of a fitted solid.
float widestRadius(const ShapeFit& fit) {
  if (fit.type == ShapeType::Cube) return 0.5f * fit.dimensions.head<2>().maxCoeff();
  return fit.type == ShapeType::Cone ? std::max(fit.radius_bottom, fit.radius_top) : fit.radius;
}

// The lowest of a cluster's points above the table [m].
float lowestPoint(const Cloud& cluster, const Plane& table) {
  float lowest = std::numeric_limits<float>::infinity();
  for (const auto& p : cluster.points)
    lowest = std::min(lowest, table.signedDistance(p.getVector3fMap()));
  return lowest;
}

// The index of the round solid whose neck fits[neck] is, or -1. The neck may be any fitted solid
// resting above the table (its points start above it): a neck 2-3 cm across came out a box too,
// and a neck fitted on the table's support stands on the table through its body (a rendered
// bottle's neck, r 18 mm, h 261 mm, beside its body, r 38 mm, h 216 mm).
int bodyOfNeck(const std::vector<ShapeFit>& fits, const std::vector<CloudPtr>& clusters,
               size_t neck, const Plane& table) {
  const ShapeFit& upper = fits[neck];
  const Eigen::Vector3f up = table.normal.normalized();
  const float bottom = lowestPoint(*clusters[neck], table);
  if (!upper.ok || !(bottom > kNeckLift)) return -1;
  for (size_t i = 0; i < fits.size(); ++i) {
    const ShapeFit& lower = fits[i];
    if (i == neck || !isRound(lower) || widestRadius(upper) >= widestRadius(lower)) continue;
    const float top = table.signedDistance(lower.center) + 0.5f * lower.height;
    const Eigen::Vector3f offset = upper.center - lower.center;
    const float axis_offset = (offset - up.dot(offset) * up).norm();
    if (std::abs(bottom - top) <= kNeckGap &&
        axis_offset <= kNeckAxisOffset * widestRadius(lower)) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

}  // namespace

void rejoinNecks(const ShapeEstimator& estimator, const Plane& table, const ViewBounds& view,
                 std::vector<CloudPtr>& clusters, std::vector<Plane>& supports,
                 std::vector<ShapeFit>& fits) {
  for (size_t neck = 0; neck < fits.size(); ++neck) {
    const int body = bodyOfNeck(fits, clusters, neck, table);
    if (body < 0) continue;
    auto joined = std::make_shared<Cloud>(*clusters[body]);
    *joined += *clusters[neck];
    ShapeFit fit = estimator.estimate(joined, supports[body], &view);
    if (!isRound(fit)) continue;
    clusters[body] = joined;
    fits[body] = fit;
    clusters.erase(clusters.begin() + neck);
    supports.erase(supports.begin() + neck);
    fits.erase(fits.begin() + neck);
    neck = static_cast<size_t>(-1);  // start over: indices moved
  }
}

}  // namespace tabletop_shapes
