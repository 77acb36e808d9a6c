#include "tabletop_shapes/core/convex_polygon.h"

#include "tabletop_shapes/core/cpu_features.h"
#include "tabletop_shapes/core/float4.h"
#include "tabletop_shapes/core/float8.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

namespace tabletop_shapes {

namespace {

// Points farther than this inside the polygon of extreme points cannot be hull vertices, even
// with the float rounding of the test and of the chain's cross products (~1e-7 m at table
// distances).
constexpr float kSurelyInside = 1e-5f;  // [m]

// Drops the points that lie surely inside their ExtremeOctagon: they cannot be on the hull, and
// sorting the rest instead of all is what makes the hull of a table plane's ~100k points cheap.
// The hull is the same.
void dropSurelyInside(std::vector<Eigen::Vector2f>& points) {
  if (points.size() < 16) return;
  ExtremeOctagon(points, kSurelyInside).keepNotSurelyInside(points);
}

// Andrew's monotone chain over points without those surely inside.
std::vector<Eigen::Vector2f> monotoneChain(std::vector<Eigen::Vector2f> points) {
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  points.erase(std::unique(points.begin(), points.end()), points.end());
  if (points.size() < 3) return points;
  auto cross = [](const Eigen::Vector2f& o, const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Eigen::Vector2f> hull(2 * points.size());
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {  // lower hull
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0.0f) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, lower = k + 1; i > 0; --i) {  // upper hull
    while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i - 1]) <= 0.0f) --k;
    hull[k++] = points[i - 1];
  }
  hull.resize(k - 1);  // the last point repeats the first
  return hull;
}

// The lane types of kLanes points (a comparison's lanes as bits: lanesOf).
template <int kLanes>
struct LaneTypes;
template <>
struct LaneTypes<4> {
  using Floats = Float4;
  using Ints = Int4;
};
#ifdef TABLETOP_SHAPES_EIGHT_LANES
template <>
struct LaneTypes<8> {
  using Floats = Float8;
  using Ints = Int8;
};
#endif

// x and y of points k .. k + kLanes - 1 of `xy` (x y pairs).
template <int kLanes>
[[gnu::always_inline]] inline void loadPoints(const float* xy, size_t k,
                                              typename LaneTypes<kLanes>::Floats& x,
                                              typename LaneTypes<kLanes>::Floats& y) {
  typename LaneTypes<kLanes>::Floats first, second;
  std::memcpy(&first, xy + 2 * k, sizeof first);
  std::memcpy(&second, xy + 2 * k + kLanes, sizeof second);
  if constexpr (kLanes == 4) {
    x = __builtin_shufflevector(first, second, 0, 2, 4, 6);
    y = __builtin_shufflevector(first, second, 1, 3, 5, 7);
  } else {
    x = __builtin_shufflevector(first, second, 0, 2, 4, 6, 8, 10, 12, 14);
    y = __builtin_shufflevector(first, second, 1, 3, 5, 7, 9, 11, 13, 15);
  }
}

// The first points reaching the highest and the lowest values along x, x + y, y and y - x, a
// lane's worth of points at a time: each lane keeps its own (the first of its points reaching
// them, the float operations of the plain loop: x + y, y - x), and the lanes are merged at the
// end (the highest value, the lowest index among the lanes holding it), so the points of the
// plain loop over all the points, whatever the width. Values never above -max (below max) and
// NaNs reach nothing: with no point reaching a direction's extreme, its index is 0.
template <int kLanes>
struct FirstExtremes {
  using Floats = typename LaneTypes<kLanes>::Floats;
  using Ints = typename LaneTypes<kLanes>::Ints;
  static constexpr float kMax = std::numeric_limits<float>::max();
  Floats highest[4], lowest[4];
  Ints at_highest[4] = {}, at_lowest[4] = {};

  FirstExtremes() {
    for (int d = 0; d < 4; ++d) highest[d] = Floats{} - kMax, lowest[d] = Floats{} + kMax;
  }

  [[gnu::always_inline]] void add(Floats x, Floats y, Ints index) {
    const Floats along[4] = {x, x + y, y, y - x};
#pragma GCC unroll 4
    for (int d = 0; d < 4; ++d) {
      const Ints higher = along[d] > highest[d], lower = along[d] < lowest[d];
      highest[d] = higher ? along[d] : highest[d];
      at_highest[d] = higher ? index : at_highest[d];
      lowest[d] = lower ? along[d] : lowest[d];
      at_lowest[d] = lower ? index : at_lowest[d];
    }
  }

  // The points' x and y from `xy` (x y pairs), kLanes points at a time; the last lanes past
  // `count` NaN.
  [[gnu::always_inline]] void addAll(const float* xy, size_t count) {
    Ints index;
    for (int lane = 0; lane < kLanes; ++lane) index[lane] = lane;
    size_t k = 0;
    for (; k + kLanes <= count; k += kLanes, index += kLanes) {
      Floats x, y;
      loadPoints<kLanes>(xy, k, x, y);
      add(x, y, index);
    }
    if (k < count) {
      Floats x = Floats{} + std::numeric_limits<float>::quiet_NaN(), y = x;
      for (size_t lane = 0; k + lane < count; ++lane) {
        x[lane] = xy[2 * (k + lane)], y[lane] = xy[2 * (k + lane) + 1];
      }
      add(x, y, index);
    }
  }

  void merge(int (&first_highest)[4], int (&first_lowest)[4]) const {
    for (int d = 0; d < 4; ++d) {
      float high = -kMax, low = kMax;
      int at_high = 0, at_low = 0;
      for (int lane = 0; lane < kLanes; ++lane) {
        const float h = highest[d][lane], l = lowest[d][lane];
        if (h > high || (h == high && at_highest[d][lane] < at_high)) {
          high = h, at_high = at_highest[d][lane];
        }
        if (l < low || (l == low && at_lowest[d][lane] < at_low)) {
          low = l, at_low = at_lowest[d][lane];
        }
      }
      first_highest[d] = at_high, first_lowest[d] = at_low;
    }
  }
};

template <int kLanes>
[[gnu::always_inline]] inline void firstExtremesInLanes(const std::vector<Eigen::Vector2f>& points,
                                                        int (&at_highest)[4], int (&at_lowest)[4]) {
  static_assert(sizeof(Eigen::Vector2f) == 2 * sizeof(float));
  FirstExtremes<kLanes> extremes;
  extremes.addAll(points.front().data(), points.size());
  extremes.merge(at_highest, at_lowest);
}

#if defined(__x86_64__) && defined(__GNUC__)
// Eight points at a time where the CPU has AVX2 (half the instructions of four).
__attribute__((target("avx2"))) void firstExtremesInEightLanes(
    const std::vector<Eigen::Vector2f>& points, int (&at_highest)[4], int (&at_lowest)[4]) {
  firstExtremesInLanes<8>(points, at_highest, at_lowest);
}
#endif

// FirstExtremes of the (not empty) points.
void firstExtremes(const std::vector<Eigen::Vector2f>& points, int (&at_highest)[4],
                   int (&at_lowest)[4]) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (cpuHasAvx2()) return firstExtremesInEightLanes(points, at_highest, at_lowest);
#endif
  firstExtremesInLanes<4>(points, at_highest, at_lowest);
}

// ExtremeOctagon::keepNotSurelyInside on the points before the last whole lane's worth: each
// lane tests its point against the eight edges (`nx`, `ny`, `offset`) with surelyInside's float
// operations. The number of points tested (a multiple of kLanes) and of those kept.
template <int kLanes>
[[gnu::always_inline]] inline std::pair<size_t, size_t> keepNotSurelyInsideInLanes(
    const Float4 (&nx)[2], const Float4 (&ny)[2], const Float4 (&offset)[2],
    std::vector<Eigen::Vector2f>& points) {
  using Floats = typename LaneTypes<kLanes>::Floats;
  using Ints = typename LaneTypes<kLanes>::Ints;
  Floats edge_nx[8], edge_ny[8], edge_offset[8];
  for (int edge = 0; edge < 8; ++edge) {
    edge_nx[edge] = Floats{} + nx[edge / 4][edge % 4];
    edge_ny[edge] = Floats{} + ny[edge / 4][edge % 4];
    edge_offset[edge] = Floats{} + offset[edge / 4][edge % 4];
  }
  const float* xy = points.front().data();
  size_t k = 0, kept = 0;
  for (; k + kLanes <= points.size(); k += kLanes) {
    Floats x, y;
    loadPoints<kLanes>(xy, k, x, y);
    Ints outside = {};
#pragma GCC unroll 8
    for (int edge = 0; edge < 8; ++edge) {
      outside |= edge_nx[edge] * x + edge_ny[edge] * y <= edge_offset[edge];
    }
    const unsigned kept_lanes = lanesOf(outside);
    for (int lane = 0; lane < kLanes; ++lane) {
      const Eigen::Vector2f p = points[k + lane];  // read before any write at or past it
      points[kept] = p;
      kept += (kept_lanes >> lane) & 1u;
    }
  }
  return {k, kept};
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx2"))) std::pair<size_t, size_t> keepNotSurelyInsideInEightLanes(
    const Float4 (&nx)[2], const Float4 (&ny)[2], const Float4 (&offset)[2],
    std::vector<Eigen::Vector2f>& points) {
  return keepNotSurelyInsideInLanes<8>(nx, ny, offset, points);
}
#endif

}  // namespace

// The extremes a lane's worth of points at a time (firstExtremes), the edges' test four edges
// at a time, with each lane's float operations those of the plain loops: the same extremes (the
// first point reaching each) and the same points kept.
ExtremeOctagon::ExtremeOctagon(const std::vector<Eigen::Vector2f>& points, float margin) {
  const float infinity = std::numeric_limits<float>::infinity();
  // Until the edges are known: 0 . p <= infinity, every point outside.
  nx_[0] = nx_[1] = ny_[0] = ny_[1] = Float4{};
  offset_[0] = offset_[1] = broadcast(infinity);
  if (points.empty()) return;
  int at_highest[4], at_lowest[4];
  firstExtremes(points, at_highest, at_lowest);
  for (int d = 0; d < 4; ++d) {
    corners_[d] = points[at_highest[d]];
    corners_[d + 4] = points[at_lowest[d]];
  }
  Float4 nx[2] = {Float4{}, Float4{}}, ny[2] = {Float4{}, Float4{}};
  Float4 offset[2] = {broadcast(-infinity), broadcast(-infinity)};
  int edges = 0;
  for (int d = 0; d < 8; ++d) {
    const Eigen::Vector2f from = corners_[d], edge = corners_[(d + 1) % 8] - from;
    const float length = edge.norm();
    if (!(length > 0.0f)) continue;
    const float edge_nx = -edge.y() / length, edge_ny = edge.x() / length;
    nx[edges / 4][edges % 4] = edge_nx, ny[edges / 4][edges % 4] = edge_ny;
    offset[edges / 4][edges % 4] = edge_nx * from.x() + edge_ny * from.y() + margin;
    ++edges;
  }
  if (edges < 3) return;  // no point is surely inside
  for (int half = 0; half < 2; ++half) {
    nx_[half] = nx[half], ny_[half] = ny[half], offset_[half] = offset[half];
  }
  usable_ = true;
}

size_t ExtremeOctagon::keepNotSurelyInside(std::vector<Eigen::Vector2f>& points) const {
  if (points.empty()) return 0;
  std::pair<size_t, size_t> tested_kept;
#if defined(__x86_64__) && defined(__GNUC__)
  if (cpuHasAvx2()) {
    tested_kept = keepNotSurelyInsideInEightLanes(nx_, ny_, offset_, points);
  } else
#endif
  {
    tested_kept = keepNotSurelyInsideInLanes<4>(nx_, ny_, offset_, points);
  }
  auto [k, kept] = tested_kept;
  for (; k < points.size(); ++k) {
    const Eigen::Vector2f p = points[k];
    points[kept] = p;
    kept += !surelyInside(p);
  }
  points.resize(kept);
  return kept;
}

bool ExtremeOctagon::within(const std::vector<Eigen::Vector2f>& hull, float tolerance) const {
  if (!usable_) return true;  // no point was surely inside
  if (hull.size() < 3) return false;
  for (const Eigen::Vector2f& corner : corners_) {
    if (!(insideDistance(hull, corner) >= -tolerance)) return false;
  }
  return true;
}

std::vector<Eigen::Vector2f> convexHull2d(std::vector<Eigen::Vector2f> points) {
  dropSurelyInside(points);
  return monotoneChain(std::move(points));
}

namespace {

// Distance of q from the line through `from` along `along` (of length `length`), positive on its
// left: inside for a counter-clockwise polygon's edge.
inline float leftOf(const Eigen::Vector2f& from, const Eigen::Vector2f& along, float length,
                    const Eigen::Vector2f& q) {
  return (along.x() * (q.y() - from.y()) - along.y() * (q.x() - from.x())) / length;
}

}  // namespace

float insideDistance(const std::vector<Eigen::Vector2f>& hull, const Eigen::Vector2f& q) {
  float nearest = std::numeric_limits<float>::max();
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f& a = hull[i];
    const Eigen::Vector2f edge = hull[(i + 1) % hull.size()] - a;
    const float length = edge.norm();
    if (length <= 0.0f) continue;
    nearest = std::min(nearest, leftOf(a, edge, length, q));
  }
  return nearest;
}

bool segmentMeetsPolygon(const std::vector<Eigen::Vector2f>& hull, const Eigen::Vector2f& a,
                         const Eigen::Vector2f& b) {
  if (hull.size() < 3) return false;
  // Cyrus-Beck: clip the segment's parameter range [0, 1] to each edge's inner half-plane.
  float enter = 0.0f, leave = 1.0f;
  const Eigen::Vector2f along = b - a;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f edge = hull[(i + 1) % hull.size()] - hull[i];
    const Eigen::Vector2f inward(-edge.y(), edge.x());  // the interior lies left of the edge
    const float at_a = inward.dot(a - hull[i]), rate = inward.dot(along);
    if (rate == 0.0f) {
      if (at_a < 0.0f) return false;  // parallel to the edge, outside it
      continue;
    }
    const float t = -at_a / rate;
    if (rate > 0.0f) {
      enter = std::max(enter, t);
    } else {
      leave = std::min(leave, t);
    }
    if (enter > leave) return false;
  }
  return true;
}

PolygonEdges::PolygonEdges(const std::vector<Eigen::Vector2f>& hull) {
  int lane = 0;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f edge = hull[(i + 1) % hull.size()] - hull[i];
    const float length = edge.norm();
    if (length <= 0.0f) continue;  // counts for nothing, as in insideDistance
    if (lane == 0) edges_.emplace_back();
    FourEdges& four = edges_.back();
    for (int copy = lane; copy < 4; ++copy) {  // this edge in its lane and the ones after
      four.from_x[copy] = hull[i].x(), four.from_y[copy] = hull[i].y();
      four.along_x[copy] = edge.x(), four.along_y[copy] = edge.y();
      four.length[copy] = length;
    }
    lane = (lane + 1) % 4;
  }
}

float PolygonEdges::insideDistance(const Eigen::Vector2f& q) const {
  // Each lane's minimum as std::min's (a NaN distance never lowers it), then the lanes'.
  Float4 nearest = broadcast(std::numeric_limits<float>::max());
  const Float4 qx = broadcast(q.x()), qy = broadcast(q.y());
  for (const FourEdges& four : edges_) {
    const Float4 distance = leftOfFour(four, qx, qy);
    nearest = distance < nearest ? distance : nearest;
  }
  return std::min(std::min(nearest[0], nearest[1]), std::min(nearest[2], nearest[3]));
}

bool PolygonEdges::insideBy(const Eigen::Vector2f& q, float margin) const {
  // The minimum exceeds the margin when every edge's distance does (a NaN one never lowers
  // the minimum, nor stops here).
  const Float4 qx = broadcast(q.x()), qy = broadcast(q.y()), limit = broadcast(margin);
  for (const FourEdges& four : edges_) {
    if (lanesOf(leftOfFour(four, qx, qy) <= limit) != 0u) return false;
  }
  return std::numeric_limits<float>::max() > margin;
}

}  // namespace tabletop_shapes
