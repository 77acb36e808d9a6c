#include "tabletop_shapes/core/round_lid.h"

#include "tabletop_shapes/core/cylinder_fit.h"
#include "tabletop_shapes/core/float4.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tabletop_shapes {
namespace {

// Top points lie within this of the box's top [m] (a lid's depth noise at 1.2 m is ~2.5 mm).
constexpr float kTopBand = 0.01f;
// The outline: the farthest top point from their centroid in each of this many directions.
constexpr int kOutlineDirections = 36;
constexpr int kMinOutlinePoints = 12;
// An outline point lies on a circle or an edge within this [m]: the voxel grid (5 mm) and the
// edge pixels' noise make a straight box edge's outline points spread over 2-3 mm.
constexpr float kOutlineBand = 0.004f;
constexpr int kRefineIterations = 20;
// A lid's outline: at least kMinShareOnCircle of it on the circle, kMinCircleOverEdges times as
// many points as on the box's edges, around at least kMinLidArcDeg. Measured on the rendered
// clutter, Kinect (cylinders typed cube / boxes): share 0.61-0.97 / 0.5-0.9, circle over edges
// 1.17-1.9 / at most 1.12 for boxes whose other tests pass (a real OSD box 5 x 5 cm, learn30:
// 32 / 31), arc 214-342 deg.
constexpr float kMinShareOnCircle = 0.6f;
constexpr float kMinCircleOverEdges = 1.15f;
constexpr float kMinLidArcDeg = 200.0f;
// At most kMaxOutside of the cluster's points may lie beyond the circle (the can holds them all
// but flying pixels behind its far edge: cans 0-0.14; boxes whose outline passed: 0.05-0.23; two
// round objects one on the other, OSD learn41: 0.40), and at most kMaxAbove over the box's top
// (a bowl in a bowl whose box ends at the lower rim, OSD learn42: 0.27; cans 0-0.02).
constexpr float kMaxOutside = 0.15f;
constexpr float kMaxAbove = 0.05f;

// The circle through three points; ok false when they are (nearly) collinear.
Circle circleThrough(const Eigen::Vector2f& a, const Eigen::Vector2f& b, const Eigen::Vector2f& c) {
  Circle circle;
  const Eigen::Vector2f ab = b - a, ac = c - a;
  const float det = 2.0f * (ab.x() * ac.y() - ab.y() * ac.x());
  if (std::abs(det) < 1e-9f) return circle;
  const float ab2 = ab.squaredNorm(), ac2 = ac.squaredNorm();
  const Eigen::Vector2f offset((ac.y() * ab2 - ab.y() * ac2) / det,
                               (ab.x() * ac2 - ac.x() * ab2) / det);
  circle.center = a + offset;
  circle.radius = offset.norm();
  circle.ok = std::isfinite(circle.radius);
  return circle;
}

bool onCircle(const Eigen::Vector2f& p, const Circle& circle) {
  return std::abs((p - circle.center).norm() - circle.radius) <= kOutlineBand;
}

int pointsOnCircle(const std::vector<Eigen::Vector2f>& points, const Circle& circle) {
  return static_cast<int>(std::count_if(
      points.begin(), points.end(), [&](const Eigen::Vector2f& p) { return onCircle(p, circle); }));
}

// Points in blocks of four, one array per coordinate (the padding NaN: on no circle). The circle
// search tests up to 7140 circles (through 3 of up to 36 outline points) against the same points.
struct PointBlocks {
  explicit PointBlocks(const std::vector<Eigen::Vector2f>& points)
      : x((points.size() + 3) / 4, broadcast(std::numeric_limits<float>::quiet_NaN())),
        y(x),
        count(static_cast<int>(points.size())) {
    for (size_t i = 0; i < points.size(); ++i) {
      x[i / 4][i % 4] = points[i].x();
      y[i / 4][i % 4] = points[i].y();
    }
  }
  std::vector<Float4> x, y;
  int count;
};

// pointsOnCircle when it exceeds `least`, else a count of at most `least`: the search keeps
// only circles better than the best so far, so the count stops once the points left cannot take
// it beyond. Each lane does onCircle's float operations ((p - c).norm(): dx dx + dy dy).
int pointsOnCircleAbove(const PointBlocks& points, const Circle& circle, int least) {
  static constexpr int kLanesSet[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};
  const Float4 cx = broadcast(circle.center.x()), cy = broadcast(circle.center.y());
  const Float4 radius = broadcast(circle.radius), band = broadcast(kOutlineBand);
  int on = 0, left = points.count;
  for (size_t k = 0; k < points.x.size() && on + left > least; ++k, left -= 4) {
    const Float4 dx = points.x[k] - cx, dy = points.y[k] - cy;
    on += kLanesSet[lanesOf(magnitude(squareRoot(dx * dx + dy * dy) - radius) <= band)];
  }
  return on;
}

// Distance of `p` to the outline of the rectangle of half sides `half` centred at the origin.
float distanceToRectangleEdges(const Eigen::Vector2f& p, const Eigen::Vector2f& half) {
  const Eigen::Vector2f excess = p.cwiseAbs() - half;
  if (excess.x() <= 0.0f && excess.y() <= 0.0f) return -std::max(excess.x(), excess.y());
  return excess.cwiseMax(0.0f).norm();
}

// The arc [deg] of the circle that `points` on it cover: a full turn less the largest gap.
float coveredArcDeg(const std::vector<Eigen::Vector2f>& points, const Circle& circle) {
  std::vector<float> angles;
  for (const Eigen::Vector2f& p : points) {
    if (std::abs((p - circle.center).norm() - circle.radius) > kOutlineBand) continue;
    const Eigen::Vector2f d = p - circle.center;
    angles.push_back(std::atan2(d.y(), d.x()));
  }
  if (angles.size() < 2) return 0.0f;
  const float gap = largestAngularGap(std::move(angles));
  return 360.0f - gap * 180.0f / static_cast<float>(kPi);
}

}  // namespace

TopOutline topOutline(const ShapeFit& box, const Cloud& cluster, float min_radius, float max_radius,
                      float tolerance) {
  TopOutline outline;
  const Eigen::Matrix3f axes = box.orientation.toRotationMatrix();
  const float top = 0.5f * box.dimensions.z();
  std::vector<Eigen::Vector2f> top_points;
  for (const auto& p : cluster.points) {
    const Eigen::Vector3f local = axes.transpose() * (p.getVector3fMap() - box.center);
    if (local.allFinite() && local.z() >= top - kTopBand) top_points.push_back(local.head<2>());
  }
  if (top_points.size() < static_cast<size_t>(kMinOutlinePoints)) return outline;
  Eigen::Vector2f centroid = Eigen::Vector2f::Zero();
  for (const Eigen::Vector2f& p : top_points) centroid += p;
  centroid /= static_cast<float>(top_points.size());

  std::vector<int> farthest(kOutlineDirections, -1);
  std::vector<float> reach(kOutlineDirections, -1.0f);
  for (size_t i = 0; i < top_points.size(); ++i) {
    const Eigen::Vector2f d = top_points[i] - centroid;
    const float angle = std::atan2(d.y(), d.x()) + static_cast<float>(kPi);
    const int direction =
        std::min(kOutlineDirections - 1,
                 static_cast<int>(angle / (2.0f * static_cast<float>(kPi)) * kOutlineDirections));
    if (d.norm() > reach[direction]) {
      reach[direction] = d.norm();
      farthest[direction] = static_cast<int>(i);
    }
  }
  std::vector<Eigen::Vector2f> points;
  for (int i : farthest) {
    if (i >= 0) points.push_back(top_points[i]);
  }
  if (points.size() < static_cast<size_t>(kMinOutlinePoints)) return outline;

  // Every circle through three outline points; the one most of them lie on (deterministic).
  Circle best;
  int best_on = 0;
  const PointBlocks blocks(points);
  for (size_t i = 0; i < points.size(); ++i) {
    for (size_t j = i + 1; j < points.size(); ++j) {
      for (size_t k = j + 1; k < points.size(); ++k) {
        const Circle circle = circleThrough(points[i], points[j], points[k]);
        if (!circle.ok || circle.radius < min_radius || circle.radius > max_radius) continue;
        const int on = pointsOnCircleAbove(blocks, circle, best_on);
        if (on > best_on) {
          best = circle;
          best_on = on;
        }
      }
    }
  }
  if (!best.ok) return outline;
  std::vector<Eigen::Vector2f> inliers;
  for (const Eigen::Vector2f& p : points) {
    if (onCircle(p, best)) inliers.push_back(p);
  }
  const Circle refined = refineCircleGeometric(inliers, best, kRefineIterations);
  if (refined.ok && refined.radius >= min_radius && refined.radius <= max_radius &&
      pointsOnCircle(points, refined) >= best_on) {
    best = refined;
  }

  outline.points = static_cast<int>(points.size());
  outline.on_circle = pointsOnCircle(points, best);
  const Eigen::Vector2f half = 0.5f * box.dimensions.head<2>();
  outline.on_box_edges =
      static_cast<int>(std::count_if(points.begin(), points.end(), [&](const Eigen::Vector2f& p) {
        return distanceToRectangleEdges(p, half) <= kOutlineBand;
      }));
  outline.arc_deg = coveredArcDeg(points, best);
  int beyond = 0, above = 0, all = 0;
  for (const auto& p : cluster.points) {
    const Eigen::Vector3f local = axes.transpose() * (p.getVector3fMap() - box.center);
    if (!local.allFinite()) continue;
    ++all;
    above += local.z() > top + kTopBand;
    beyond += (local.head<2>() - best.center).norm() > best.radius + tolerance;
  }
  outline.outside = static_cast<float>(beyond) / static_cast<float>(all);
  outline.above = static_cast<float>(above) / static_cast<float>(all);
  outline.center = best.center;
  outline.radius = best.radius;
  return outline;
}

bool isRoundLid(const TopOutline& outline) {
  return outline.points > 0 &&
         outline.on_circle >= kMinShareOnCircle * static_cast<float>(outline.points) &&
         outline.on_circle >= kMinCircleOverEdges * static_cast<float>(outline.on_box_edges) &&
         outline.arc_deg >= kMinLidArcDeg && outline.outside <= kMaxOutside &&
         outline.above <= kMaxAbove;
}

ShapeFit cylinderUnderLid(const ShapeFit& box, const TopOutline& outline) {
  ShapeFit cylinder = box;
  cylinder.type = ShapeType::Cylinder;
  cylinder.center =
      box.center + box.orientation * Eigen::Vector3f(outline.center.x(), outline.center.y(), 0.0f);
  cylinder.radius = outline.radius;
  cylinder.height = box.dimensions.z();
  cylinder.dimensions = Eigen::Vector3f::Zero();
  cylinder.faces_seen = 0;
  return cylinder;
}

}  // namespace tabletop_shapes
