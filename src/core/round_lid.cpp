#include "tabletop_shapes/core/round_lid.h"

#include "tabletop_shapes/core/cylinder_fit.h"
#include "tabletop_shapes/core/cpu_features.h"
#include "tabletop_shapes/core/float4.h"
#include "tabletop_shapes/core/float8.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

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
// A lid partly hidden by a taller neighbour in front: the rim on its far side from the camera,
// which nothing in front can hide, lies on the circle (at least kMinFarShareOnCircle of the
// outline points there), the circle's far half stays within kMaxFarOverhang of the box's
// footprint, and the box's two top corners farthest from the camera lie beyond kFarCornerGap of
// every point (the camera sees past the rim there; a box's corner has a point within half a
// voxel diagonal, 3.5 mm, plus noise). Measured on the rendered clutter (Kinect, seed 2012): the
// cans still typed cube had far corners 5.8-16.5 mm from their points, far shares 0.57-0.95 and
// overhangs 1.8-13 mm where the other tests passed; of 211 boxes whose box won, 22 had both far
// corners empty, all but one with a far share of at most 0.47 or a circle 19-188 mm beyond the
// footprint; that one (r 57 mm over a 96 x 88 mm box) stays a box by the residual comparison.
constexpr float kMinFarShareOnCircle = 0.55f;
constexpr float kMaxFarOverhang = 0.015f;
constexpr float kFarCornerGap = 0.005f;

// The circles through a, b and each of four third points (lanes cx, cy), each lane with the
// float operations of the circle through three points; `ok` (all bits set) where the points are
// not (nearly) collinear and the radius is finite.
struct FourCircles {
  Float4 center_x, center_y, radius;
  Int4 ok;
};
FourCircles circlesThrough(const Eigen::Vector2f& a, const Eigen::Vector2f& b, Float4 cx,
                           Float4 cy) {
  const float ab_x = b.x() - a.x(), ab_y = b.y() - a.y();
  const Float4 ac_x = cx - a.x(), ac_y = cy - a.y();
  const Float4 det = 2.0f * (ab_x * ac_y - ab_y * ac_x);
  const float ab2 = ab_x * ab_x + ab_y * ab_y;
  const Float4 ac2 = ac_x * ac_x + ac_y * ac_y;
  const Float4 offset_x = (ac_y * ab2 - ab_y * ac2) / det;
  const Float4 offset_y = (ab_x * ac2 - ac_x * ab2) / det;
  FourCircles circles;
  circles.center_x = a.x() + offset_x;
  circles.center_y = a.y() + offset_y;
  circles.radius = squareRoot(offset_x * offset_x + offset_y * offset_y);
  const Float4 infinity = broadcast(std::numeric_limits<float>::infinity());
  circles.ok = ~(magnitude(det) < 1e-9f) & (magnitude(circles.radius) < infinity);
  return circles;
}

bool onCircle(const Eigen::Vector2f& p, const Circle& circle) {
  return std::abs((p - circle.center).norm() - circle.radius) <= kOutlineBand;
}

int pointsOnCircle(const std::vector<Eigen::Vector2f>& points, const Circle& circle) {
  return static_cast<int>(std::count_if(
      points.begin(), points.end(), [&](const Eigen::Vector2f& p) { return onCircle(p, circle); }));
}

// Points in blocks of four, one array per coordinate (the padding NaN: on no circle), an even
// number of blocks (for pointsOnCircleAboveInEightLanes). The circle search tests up to 7140
// circles (through 3 of up to 36 outline points) against the same points.
struct PointBlocks {
  explicit PointBlocks(const std::vector<Eigen::Vector2f>& points)
      : x((points.size() + 7) / 8 * 2, broadcast(std::numeric_limits<float>::quiet_NaN())),
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

// The lane operations pointsOnCircleAboveInLanes takes from its width: the lane types, the
// square root (correctly rounded, as std::sqrt) and the number of lanes a comparison sets.
struct FourLanes {
  using Floats = Float4;
  using Ints = Int4;
  static Float4 root(Float4 value) { return squareRoot(value); }
  static int countSet(Int4 mask) {
    static constexpr int kLanesSet[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};
    return kLanesSet[lanesOf(mask)];
  }
};

// pointsOnCircle when it exceeds `least`, else a count of at most `least`: the search keeps
// only circles better than the best so far, so the count stops once the points left cannot take
// it beyond (checked a lane's worth of points at a time: where it stops, the count depends on
// the width). Each lane does onCircle's float operations ((p - c).norm(): dx dx + dy dy), so
// every width gives the same count where it exceeds `least`.
template <typename Lanes>
[[gnu::always_inline]] inline int pointsOnCircleAboveInLanes(const PointBlocks& points,
                                                             const Circle& circle, int least) {
  using Floats = typename Lanes::Floats;
  using Ints = typename Lanes::Ints;
  constexpr int kLanes = sizeof(Floats) / sizeof(float);
  const Floats cx = Floats{} + circle.center.x(), cy = Floats{} + circle.center.y();
  const Floats radius = Floats{} + circle.radius, band = Floats{} + kOutlineBand;
  const float* xs = reinterpret_cast<const float*>(points.x.data());
  const float* ys = reinterpret_cast<const float*>(points.y.data());
  const size_t floats = 4 * points.x.size();
  int on = 0, left = points.count;
  for (size_t k = 0; k < floats && on + left > least; k += kLanes, left -= kLanes) {
    Floats x, y;
    std::memcpy(&x, xs + k, sizeof x);
    std::memcpy(&y, ys + k, sizeof y);
    const Floats dx = x - cx, dy = y - cy;
    const Floats off = Lanes::root(dx * dx + dy * dy) - radius;
    on += Lanes::countSet((Floats)((Ints)off & 0x7fffffff) <= band);
  }
  return on;
}

// Out of line, as the eight-lane one: inlined, it cost the circle search's loop registers.
[[gnu::noinline]] int pointsOnCircleAbove(const PointBlocks& points, const Circle& circle,
                                          int least) {
  return pointsOnCircleAboveInLanes<FourLanes>(points, circle, least);
}

#if defined(__x86_64__) && defined(__GNUC__)
struct EightLanes {
  using Floats = Float8;
  using Ints = Int8;
  __attribute__((target("avx2"))) static Float8 root(Float8 value) { return squareRoot(value); }
  __attribute__((target("avx2,popcnt"))) static int countSet(Int8 mask) {
    return __builtin_popcount(lanesOf(mask));
  }
};

// pointsOnCircleAbove eight points at a time where the CPU has AVX2.
__attribute__((target("avx2,popcnt"))) int pointsOnCircleAboveInEightLanes(
    const PointBlocks& points, const Circle& circle, int least) {
  return pointsOnCircleAboveInLanes<EightLanes>(points, circle, least);
}
#else
// Without AVX2 (cpuHasAvx2() false): never called.
int pointsOnCircleAboveInEightLanes(const PointBlocks& points, const Circle& circle, int least) {
  return pointsOnCircleAbove(points, circle, least);
}
#endif

// Outline points farther than the band beyond `circle`.
int pointsBeyondCircle(const std::vector<Eigen::Vector2f>& points, const Circle& circle) {
  return static_cast<int>(
      std::count_if(points.begin(), points.end(), [&](const Eigen::Vector2f& p) {
        return (p - circle.center).norm() - circle.radius > kOutlineBand;
      }));
}

// Every circle through three outline points, radius `min_radius`-`max_radius`; the one most of
// them lie on (deterministic), refined on those. `containing`: only circles with at most one
// outline point beyond them (a lid holds all of its top points; the outline of a lid cut by a
// neighbour follows the cut inside the circle, and a circle through the cut and part of the rim
// leaves the rest of the rim outside).
Circle bestCircle(const std::vector<Eigen::Vector2f>& points, float min_radius, float max_radius,
                  bool containing) {
  Circle best;
  int best_on = 0;
  const PointBlocks blocks(points);
  const bool eight_lanes = cpuHasAvx2();
  // The third points four at a time, from arrays with three NaNs past the points.
  const size_t n = points.size();
  std::vector<float> xs(n + 3, std::numeric_limits<float>::quiet_NaN()), ys(xs);
  for (size_t k = 0; k < n; ++k) xs[k] = points[k].x(), ys[k] = points[k].y();
  auto fourFrom = [](const std::vector<float>& values, size_t k) {
    Float4 lanes;
    std::memcpy(&lanes, values.data() + k, sizeof lanes);
    return lanes;
  };
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      for (size_t k0 = j + 1; k0 < n; k0 += 4) {
        const FourCircles circles =
            circlesThrough(points[i], points[j], fourFrom(xs, k0), fourFrom(ys, k0));
        const Int4 in_range =
            circles.ok & (circles.radius >= min_radius) & (circles.radius <= max_radius);
        // The lanes in k's order, the last block's lanes past the points left out.
        const unsigned lanes = lanesOf(in_range) & ((1u << std::min<size_t>(4, n - k0)) - 1);
        for (unsigned rest = lanes; rest != 0; rest &= rest - 1) {
          const int lane = __builtin_ctz(rest);
          Circle circle;
          circle.center = Eigen::Vector2f(circles.center_x[lane], circles.center_y[lane]);
          circle.radius = circles.radius[lane];
          circle.ok = true;
          const int on = eight_lanes ? pointsOnCircleAboveInEightLanes(blocks, circle, best_on)
                                     : pointsOnCircleAbove(blocks, circle, best_on);
          if (on > best_on && (!containing || pointsBeyondCircle(points, circle) <= 1)) {
            best = circle;
            best_on = on;
          }
        }
      }
    }
  }
  if (!best.ok) return best;
  std::vector<Eigen::Vector2f> inliers;
  for (const Eigen::Vector2f& p : points) {
    if (onCircle(p, best)) inliers.push_back(p);
  }
  const Circle refined = refineCircleGeometric(inliers, best, kRefineIterations);
  if (refined.ok && refined.radius >= min_radius && refined.radius <= max_radius &&
      pointsOnCircle(points, refined) >= best_on) {
    return refined;
  }
  return best;
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
    if (!onCircle(p, circle)) continue;
    const Eigen::Vector2f d = p - circle.center;
    angles.push_back(std::atan2(d.y(), d.x()));
  }
  if (angles.size() < 2) return 0.0f;
  const float gap = largestAngularGap(std::move(angles));
  return 360.0f - gap * 180.0f / static_cast<float>(kPi);
}

// The outline of the top points of `cluster` (those within kTopBand of the top of `box`), in the
// box's x / y frame from its centre: the farthest top point from their centroid in each of
// kOutlineDirections directions. Empty with too few.
std::vector<Eigen::Vector2f> outlineOfTop(const ShapeFit& box, const Cloud& cluster) {
  const Eigen::Matrix3f axes = box.orientation.toRotationMatrix();
  const float top = 0.5f * box.dimensions.z();
  std::vector<Eigen::Vector2f> top_points;
  for (const auto& p : cluster.points) {
    const Eigen::Vector3f local = axes.transpose() * (p.getVector3fMap() - box.center);
    if (local.allFinite() && local.z() >= top - kTopBand) top_points.push_back(local.head<2>());
  }
  if (top_points.size() < static_cast<size_t>(kMinOutlinePoints)) return {};
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
  if (points.size() < static_cast<size_t>(kMinOutlinePoints)) return {};
  return points;
}

// How well `circle` and the box's own top face explain the outline `points` (outlineOfTop) and
// how the cluster's points lie around it (TopOutline).
TopOutline describeOutline(const ShapeFit& box, const Cloud& cluster,
                           const std::vector<Eigen::Vector2f>& points, const Circle& circle,
                           float tolerance) {
  TopOutline outline;
  outline.points = static_cast<int>(points.size());
  outline.on_circle = pointsOnCircle(points, circle);
  const Eigen::Vector2f half = 0.5f * box.dimensions.head<2>();
  outline.on_box_edges =
      static_cast<int>(std::count_if(points.begin(), points.end(), [&](const Eigen::Vector2f& p) {
        return distanceToRectangleEdges(p, half) <= kOutlineBand;
      }));
  outline.arc_deg = coveredArcDeg(points, circle);
  const Eigen::Matrix3f axes = box.orientation.toRotationMatrix();
  const float top = 0.5f * box.dimensions.z();
  int beyond = 0, above = 0, all = 0;
  for (const auto& p : cluster.points) {
    const Eigen::Vector3f local = axes.transpose() * (p.getVector3fMap() - box.center);
    if (!local.allFinite()) continue;
    ++all;
    above += local.z() > top + kTopBand;
    beyond += (local.head<2>() - circle.center).norm() > circle.radius + tolerance;
  }
  outline.outside = static_cast<float>(beyond) / static_cast<float>(all);
  outline.above = static_cast<float>(above) / static_cast<float>(all);
  outline.center = circle.center;
  outline.radius = circle.radius;
  return outline;
}

// The distance from the two top corners of `box` farthest from the camera (the origin of the
// cluster's frame) to the nearest point of `cluster`: the smaller of the two.
float farTopCornerGap(const ShapeFit& box, const Cloud& cluster) {
  const Eigen::Matrix3f axes = box.orientation.toRotationMatrix();
  const Eigen::Vector3f half = 0.5f * box.dimensions;
  std::vector<std::pair<float, float>> corners;  // distance from the camera, gap to the points
  for (const Eigen::Vector2f& sign : {Eigen::Vector2f(-1, -1), Eigen::Vector2f(1, -1),
                                      Eigen::Vector2f(-1, 1), Eigen::Vector2f(1, 1)}) {
    const Eigen::Vector3f corner =
        box.center + axes * Eigen::Vector3f(sign.x() * half.x(), sign.y() * half.y(), half.z());
    float gap = std::numeric_limits<float>::max();
    for (const auto& p : cluster.points) gap = std::min(gap, (p.getVector3fMap() - corner).norm());
    corners.emplace_back(corner.norm(), gap);
  }
  std::sort(corners.rbegin(), corners.rend());
  return std::min(corners[0].second, corners[1].second);
}

}  // namespace

TopOutline topOutline(const ShapeFit& box, const Cloud& cluster, float min_radius, float max_radius,
                      float tolerance) {
  const std::vector<Eigen::Vector2f> points = outlineOfTop(box, cluster);
  if (points.empty()) return TopOutline();
  const Circle circle = bestCircle(points, min_radius, max_radius, false);
  if (!circle.ok) return TopOutline();
  return describeOutline(box, cluster, points, circle, tolerance);
}

TopOutline hiddenLidOutline(const ShapeFit& box, const Cloud& cluster, float min_radius,
                            float max_radius, float tolerance) {
  // Only a box whose far corners are empty can be around a lid, and most boxes' are not: the
  // corners first, the search for the circle only then (on the 16-object speed scene, callgrind,
  // 38.3M instructions per frame with the search for every box, 1.4M so).
  const float far_corner_gap = farTopCornerGap(box, cluster);
  if (far_corner_gap < kFarCornerGap) return TopOutline();
  const std::vector<Eigen::Vector2f> points = outlineOfTop(box, cluster);
  if (points.empty()) return TopOutline();
  const Circle circle = bestCircle(points, min_radius, max_radius, true);
  if (!circle.ok) return TopOutline();
  TopOutline outline = describeOutline(box, cluster, points, circle, tolerance);
  outline.far_corner_gap = far_corner_gap;
  // The camera (the cluster frame's origin) seen from the circle's centre, in the box's frame.
  const Eigen::Matrix3f axes = box.orientation.toRotationMatrix();
  const Eigen::Vector2f camera = (axes.transpose() * -box.center).head<2>();
  if (!camera.allFinite() || (camera - circle.center).norm() < 1e-6f) return outline;
  const Eigen::Vector2f towards_camera = (camera - circle.center).normalized();
  int far = 0, far_on = 0;
  for (const Eigen::Vector2f& p : points) {
    if ((p - circle.center).dot(towards_camera) >= 0.0f) continue;
    ++far;
    far_on += onCircle(p, circle);
  }
  outline.far_share = far > 0 ? static_cast<float>(far_on) / static_cast<float>(far) : 0.0f;
  // The far half of the circle, every 5 degrees: how far it reaches beyond the footprint.
  const Eigen::Vector2f half = 0.5f * box.dimensions.head<2>();
  outline.far_overhang = 0.0f;
  for (int step = 0; step < 72; ++step) {
    const float angle = static_cast<float>(step) * static_cast<float>(kPi) / 36.0f;
    const Eigen::Vector2f direction(std::cos(angle), std::sin(angle));
    if (direction.dot(towards_camera) >= 0.0f) continue;
    const Eigen::Vector2f rim = circle.center + circle.radius * direction;
    outline.far_overhang = std::max(outline.far_overhang, (rim.cwiseAbs() - half).maxCoeff());
  }
  return outline;
}

bool isRoundLid(const TopOutline& outline) {
  return outline.points > 0 &&
         outline.on_circle >= kMinShareOnCircle * static_cast<float>(outline.points) &&
         outline.on_circle >= kMinCircleOverEdges * static_cast<float>(outline.on_box_edges) &&
         outline.arc_deg >= kMinLidArcDeg && outline.outside <= kMaxOutside &&
         outline.above <= kMaxAbove;
}

bool isPartlyHiddenLid(const TopOutline& outline) {
  return outline.points > 0 && outline.far_share >= kMinFarShareOnCircle &&
         outline.far_overhang <= kMaxFarOverhang && outline.far_corner_gap >= kFarCornerGap &&
         outline.outside <= kMaxOutside && outline.above <= kMaxAbove;
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
  cylinder.bounding_box = false;  // the box may be the cluster's bounding box (no model passed)
  cylinder.reason.clear();
  return cylinder;
}

}  // namespace tabletop_shapes
