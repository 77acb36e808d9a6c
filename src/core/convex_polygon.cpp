#include "tabletop_shapes/core/convex_polygon.h"

#include <algorithm>
#include <limits>

namespace tabletop_shapes {

std::vector<Eigen::Vector2f> convexHull2d(std::vector<Eigen::Vector2f> points) {
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
