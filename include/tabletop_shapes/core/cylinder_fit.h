// §3.3 cylinder fit in the table frame, and the truncated cone (beyond the paper).
#pragma once

#include "tabletop_shapes/core/normals.h"

namespace tabletop_shapes {

struct Circle {
  Eigen::Vector2f center = Eigen::Vector2f::Zero();
  float radius = 0.0f;
  float rmse = 0.0f;  // RMS geometric distance of the points to the circle
  bool ok = false;
};

// Algebraic circle by OLS, eq. 10-16 (biased on short arcs: use it as the initial guess).
Circle fitCircleAlgebraic(const std::vector<Eigen::Vector2f>& points);
// Geometric least squares (Gauss-Newton / Levenberg-Marquardt on |p - c| - r).
Circle refineCircleGeometric(const std::vector<Eigen::Vector2f>& points, const Circle& initial,
                             int max_iterations);
// The largest gap [rad] between consecutive angles around the circle (atan2 values; at least
// two): a full turn less it is the arc they cover.
float largestAngularGap(std::vector<float> angles);

// Axis = table normal. center = centre of the solid (half the height above the table).
ShapeFit fitCylinder(const NormalCloud& object, const Plane& table, const CylinderParams& params);
// Radius linear in height above the table. Always returns a Cone (ok when the fit worked).
ShapeFit fitCone(const NormalCloud& object, const Plane& table, const CylinderParams& cylinder,
                 const ConeParams& params);
// A round object: a Cone when its taper is significant given the noise, measurable (>= 4 mm) and,
// narrowing upwards, straight; else a Cylinder (through the lower half of the side wall when it
// narrows upwards in steps, as a bottle's body, shoulder and neck do).
ShapeFit fitRoundObject(const NormalCloud& object, const Plane& table,
                        const CylinderParams& cylinder, const ConeParams& cone);

// A cylinder lying on its side (a can, a tin on its rim): axis horizontal, along the principal
// direction of the normals that gives the closer circle through the side wall in the vertical
// plane across it; length = the points' extent along the axis. The axis points towards the
// camera (origin). Rejected (with the reason) when its bottom sinks into the table beyond noise.
ShapeFit fitLyingCylinder(const NormalCloud& object, const Plane& table,
                          const CylinderParams& params);

// Distance [m] of `point` to the surface of the fitted cylinder or truncated cone `round` (side
// wall, top or bottom disc), from inside or outside alike.
float distanceToRoundObject(const ShapeFit& round, const Eigen::Vector3f& point);
// Distance [m] of `point` to the part of that surface the camera (at the origin) sees: the
// side wall facing it and the top disc when the camera is above it. A point behind the
// visible surface (seen through the solid) or beside a solid too small is far from it.
float distanceToVisibleRoundSurface(const ShapeFit& round, const Eigen::Vector3f& point);
// The same for every point of `points`, into `distances` (the solid's view from the camera
// worked out once).
void distancesToVisibleRoundSurface(const ShapeFit& round, const NormalCloud& points,
                                    std::vector<float>& distances);

}  // namespace tabletop_shapes
