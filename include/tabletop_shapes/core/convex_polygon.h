// Convex polygons in a plane: the table's hull, object footprints on the table.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace tabletop_shapes {

// Convex hull (Andrew's monotone chain), counter-clockwise, without collinear points; fewer
// than 3 points when the input is degenerate.
std::vector<Eigen::Vector2f> convexHull2d(std::vector<Eigen::Vector2f> points);

// Distance of q inside the counter-clockwise convex polygon to its boundary (negative outside).
float insideDistance(const std::vector<Eigen::Vector2f>& hull, const Eigen::Vector2f& q);

}  // namespace tabletop_shapes
