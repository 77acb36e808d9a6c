#include "tabletop_shapes/core/convex_polygon.h"

#include <algorithm>
#include <limits>

namespace tabletop_shapes {

namespace {

// Drops the points strictly inside the octagon of the extreme points in 8 directions (Akl and
// Toussaint 1978): they are no hull vertices. A table's 50-100k inliers shrink to a few hundred,
// and the sort below, the bulk of the hull's cost, shrinks with them.
void dropInteriorPoints(std::vector<Eigen::Vector2f>& points) {
  constexpr size_t kMinPointsWorthIt = 64;
  if (points.size() < kMinPointsWorthIt) return;
  // Counter-clockwise directions: the extreme points in them run counter-clockwise on the hull.
  static const Eigen::Vector2f kDirections[8] = {{-1, 0}, {-1, -1}, {0, -1}, {1, -1},
                                                 {1, 0},  {1, 1},   {0, 1},  {-1, 1}};
  Eigen::Vector2f extreme[8];
  float best[8];
  for (int d = 0; d < 8; ++d) {
    extreme[d] = points.front();
    best[d] = kDirections[d].dot(points.front());
  }
  Eigen::Vector2f low = points.front(), high = low;
  for (const Eigen::Vector2f& p : points) {
    for (int d = 0; d < 8; ++d) {
      const float along = kDirections[d].dot(p);
      if (along > best[d]) best[d] = along, extreme[d] = p;
    }
    low = low.cwiseMin(p), high = high.cwiseMax(p);
  }
  std::vector<Eigen::Vector2d> octagon;
  for (const Eigen::Vector2f& e : extreme) {
    const Eigen::Vector2d v = e.cast<double>();
    if (octagon.empty() || v != octagon.back()) octagon.push_back(v);
  }
  while (octagon.size() > 1 && octagon.back() == octagon.front()) octagon.pop_back();
  if (octagon.size() < 3) return;
  // Inside by more than rounding can blur: a point near an edge stays for the exact test below.
  const double tolerance = 1e-9 * (high - low).cast<double>().squaredNorm();
  auto strictlyInside = [&](const Eigen::Vector2f& point) {
    const Eigen::Vector2d p = point.cast<double>();
    for (size_t i = 0; i < octagon.size(); ++i) {
      const Eigen::Vector2d& a = octagon[i];
      const Eigen::Vector2d edge = octagon[(i + 1) % octagon.size()] - a;
      if (!(edge.x() * (p.y() - a.y()) - edge.y() * (p.x() - a.x()) > tolerance)) return false;
    }
    return true;
  };
  points.erase(std::remove_if(points.begin(), points.end(), strictlyInside), points.end());
}

}  // namespace

std::vector<Eigen::Vector2f> convexHull2d(std::vector<Eigen::Vector2f> points) {
  dropInteriorPoints(points);
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

float insideDistance(const std::vector<Eigen::Vector2f>& hull, const Eigen::Vector2f& q) {
  float nearest = std::numeric_limits<float>::max();
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f& a = hull[i];
    const Eigen::Vector2f edge = hull[(i + 1) % hull.size()] - a;
    const float length = edge.norm();
    if (length <= 0.0f) continue;
    // Left of a counter-clockwise edge is inside.
    const float distance = (edge.x() * (q.y() - a.y()) - edge.y() * (q.x() - a.x())) / length;
    nearest = std::min(nearest, distance);
  }
  return nearest;
}

}  // namespace tabletop_shapes
