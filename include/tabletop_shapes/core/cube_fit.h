// §3.2 box fit: RANSAC planes with distance + normal-angle constraints, a priority queue,
// OLS refinement, edges from the supports projected on the intersection lines.
// Beyond the paper: the table is the box's bottom face, so one face is enough.
#pragma once

#include "tabletop_shapes/core/normals.h"

namespace tabletop_shapes {

// `table` is the support plane (normal up). Result: type Cube; ok == false with a reason
// when no consistent set of faces is found. center = centre of the solid box.
ShapeFit fitCube(const NormalCloud& object, const Plane& table, const CubeParams& params);

// Distance [m] of `point` to the surface of the fitted box `box` (any face, the bottom one too),
// from inside or outside alike.
float distanceToBox(const ShapeFit& box, const Eigen::Vector3f& point);

}  // namespace tabletop_shapes
