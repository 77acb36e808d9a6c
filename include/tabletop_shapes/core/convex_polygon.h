// Convex polygons in a plane: the table's hull, object footprints on the table.
#pragma once

#include "tabletop_shapes/core/float4.h"

#include <Eigen/Core>

#include <vector>

namespace tabletop_shapes {

// Convex hull (Andrew's monotone chain), counter-clockwise, without collinear points; fewer
// than 3 points when the input is degenerate.
std::vector<Eigen::Vector2f> convexHull2d(std::vector<Eigen::Vector2f> points);

// Akl-Toussaint's octagon of a point set: its points extreme along x, x + y, y, y - x and the
// opposite directions (the first point reaching each), counter-clockwise. A point farther than
// `margin` inside it is no vertex of the convex hull of any set whose hull holds the octagon.
class ExtremeOctagon {
 public:
  ExtremeOctagon(const std::vector<Eigen::Vector2f>& points, float margin);
  // False for every point when the octagon has fewer than 3 edges (fewer than 3 distinct
  // extreme points).
  bool surelyInside(const Eigen::Vector2f& p) const {
    const Float4 x = broadcast(p.x()), y = broadcast(p.y());
    return lanesOf((nx_[0] * x + ny_[0] * y <= offset_[0]) |
                   (nx_[1] * x + ny_[1] * y <= offset_[1])) == 0u;
  }
  // Keeps the points not surelyInside, in their order, at the front of `points` (resized to
  // them); their number. Several points at a time: the points surelyInside keeps, one by one.
  size_t keepNotSurelyInside(std::vector<Eigen::Vector2f>& points) const;
  // True when no corner lies farther than `tolerance` outside the counter-clockwise convex
  // `hull`: with a tolerance below the margin, the points surely inside the octagon lie in it.
  bool within(const std::vector<Eigen::Vector2f>& hull, float tolerance) const;

 private:
  Eigen::Vector2f corners_[8];
  // Each edge as a unit inward normal and offset: inside when normal . p > offset. Unused lanes
  // (fewer than 8 edges) hold 0 . p <= -infinity, never outside.
  Float4 nx_[2], ny_[2], offset_[2];
  bool usable_ = false;  // at least 3 edges
};

// Distance of q inside the counter-clockwise convex polygon to its boundary (negative outside).
float insideDistance(const std::vector<Eigen::Vector2f>& hull, const Eigen::Vector2f& q);

// True when the segment a -> b meets the counter-clockwise convex polygon (touching counts).
bool segmentMeetsPolygon(const std::vector<Eigen::Vector2f>& hull, const Eigen::Vector2f& a,
                         const Eigen::Vector2f& b);

// A convex polygon's edges with their lengths, for many tests against one polygon (the table's
// hull against every point of a frame): the same values as insideDistance without its square
// root per edge and test, four edges at a time.
class PolygonEdges {
 public:
  PolygonEdges() = default;
  explicit PolygonEdges(const std::vector<Eigen::Vector2f>& hull);
  // insideDistance(hull, q), bit for bit (but for the sign of a zero).
  float insideDistance(const Eigen::Vector2f& q) const;
  // insideDistance(hull, q) > margin, stopping at the first four edges that q is not that far
  // inside of.
  bool insideBy(const Eigen::Vector2f& q, float margin) const;

 private:
  // Four edges, one per lane: each starts at `from` and runs `along` to the next vertex.
  struct FourEdges {
    Float4 from_x, from_y, along_x, along_y, length;
  };
  // Of non-zero length, the last four padded with copies of the last edge (a repeated edge
  // changes neither a minimum nor a test of every edge).
  std::vector<FourEdges> edges_;
  // q's distance from each of the four edges' lines, positive on its left (leftOf's float
  // operations, lane by lane).
  static Float4 leftOfFour(const FourEdges& edges, Float4 qx, Float4 qy) {
    return (edges.along_x * (qy - edges.from_y) - edges.along_y * (qx - edges.from_x)) /
           edges.length;
  }
};

}  // namespace tabletop_shapes
