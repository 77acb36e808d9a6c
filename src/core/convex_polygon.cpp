#include "tabletop_shapes/core/convex_polygon.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tabletop_shapes {

namespace {

// Points farther than this inside the polygon of extreme points cannot be hull vertices, even
// with the float rounding of the test and of the chain's cross products (~1e-7 m at table
// distances).
constexpr float kSurelyInside = 1e-5f;  // [m]

// Drops the points that lie surely inside the octagon of the extreme points along x, y and the
// two diagonals (Akl-Toussaint): they cannot be on the hull, and sorting the rest instead of
// all is what makes the hull of a table plane's ~100k points cheap. The hull is the same.
void dropSurelyInside(std::vector<Eigen::Vector2f>& points) {
  if (points.size() < 16) return;
  // The points with the largest x, x + y, y, y - x, -x, -x - y, -y, x - y: counter-clockwise
  // on the hull (support points of directions at 0, 45, ..., 315 deg).
  const Eigen::Vector2f* extreme[8];
  float best[8];
  for (int d = 0; d < 8; ++d) extreme[d] = &points[0], best[d] = -std::numeric_limits<float>::max();
  for (const Eigen::Vector2f& p : points) {
    const float x = p.x(), y = p.y();
    const float along[8] = {x, x + y, y, y - x, -x, -x - y, -y, x - y};
    for (int d = 0; d < 8; ++d) {
      if (along[d] > best[d]) best[d] = along[d], extreme[d] = &p;
    }
  }
  // Each edge as a unit inward normal and offset: inside when normal . p > offset.
  float nx[8], ny[8], offset[8];
  int edges = 0;
  for (int d = 0; d < 8; ++d) {
    const Eigen::Vector2f from = *extreme[d], edge = *extreme[(d + 1) % 8] - from;
    const float length = edge.norm();
    if (!(length > 0.0f)) continue;
    nx[edges] = -edge.y() / length, ny[edges] = edge.x() / length;
    offset[edges] = nx[edges] * from.x() + ny[edges] * from.y() + kSurelyInside;
    ++edges;
  }
  if (edges < 3) return;
  auto surelyInside = [&](const Eigen::Vector2f& p) {
    for (int e = 0; e < edges; ++e) {
      if (nx[e] * p.x() + ny[e] * p.y() <= offset[e]) return false;
    }
    return true;
  };
  points.erase(std::remove_if(points.begin(), points.end(), surelyInside), points.end());
}

}  // namespace

std::vector<Eigen::Vector2f> convexHull2d(std::vector<Eigen::Vector2f> points) {
  dropSurelyInside(points);
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
  edges_.reserve(hull.size());
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f edge = hull[(i + 1) % hull.size()] - hull[i];
    const float length = edge.norm();
    if (length <= 0.0f) continue;  // counts for nothing, as in insideDistance
    edges_.push_back({hull[i], edge, length});
  }
}

float PolygonEdges::insideDistance(const Eigen::Vector2f& q) const {
  float nearest = std::numeric_limits<float>::max();
  for (const Edge& edge : edges_)
    nearest = std::min(nearest, leftOf(edge.from, edge.along, edge.length, q));
  return nearest;
}

bool PolygonEdges::insideBy(const Eigen::Vector2f& q, float margin) const {
  // The minimum exceeds the margin when every edge's distance does (a NaN one never lowers
  // the minimum, nor stops here).
  for (const Edge& edge : edges_) {
    if (leftOf(edge.from, edge.along, edge.length, q) <= margin) return false;
  }
  return std::numeric_limits<float>::max() > margin;
}

}  // namespace tabletop_shapes
