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

// True when the segment a -> b meets the counter-clockwise convex polygon (touching counts).
bool segmentMeetsPolygon(const std::vector<Eigen::Vector2f>& hull, const Eigen::Vector2f& a,
                         const Eigen::Vector2f& b);

// A convex polygon's edges with their lengths, for many tests against one polygon (the table's
// hull against every point of a frame): the same values as insideDistance without its square
// root per edge and test.
class PolygonEdges {
 public:
  PolygonEdges() = default;
  explicit PolygonEdges(const std::vector<Eigen::Vector2f>& hull);
  // insideDistance(hull, q), bit for bit.
  float insideDistance(const Eigen::Vector2f& q) const;
  // insideDistance(hull, q) > margin, stopping at the first edge that q is not that far inside.
  bool insideBy(const Eigen::Vector2f& q, float margin) const;

 private:
  struct Edge {
    Eigen::Vector2f from, along;  // along: to the next vertex
    float length;
  };
  std::vector<Edge> edges_;  // of non-zero length
};

}  // namespace tabletop_shapes
