// §3.2 box fit: RANSAC planes with distance + normal-angle constraints, a priority queue,
// OLS refinement, edges from the supports projected on the intersection lines.
// Beyond the paper: the table is the box's bottom face, so one face is enough.
#pragma once

#include "tabletop_shapes/core/normals.h"

namespace tabletop_shapes {

// What the camera's edge smear (ShapeEstimatorParams::edge_bleed_px) adds at a box's hidden ends:
// those come from the seen faces' points, whose rims an active-stereo camera smears over the
// background beyond the silhouette, so each hidden end moves in by `distance` [m], except one
// facing a direction in `cut_directions` (the image border cut the object there: no smear). A box
// the border cut whose top face is seen takes its yaw from that face: a side face seen only as a
// strip along the cut is not used.
struct SilhouetteSmear {
  float distance = 0.0f;
  std::vector<Eigen::Vector3f> cut_directions;
};

// `table` is the support plane (normal up). Result: type Cube; ok == false with a reason
// when no consistent set of faces is found. center = centre of the solid box.
ShapeFit fitCube(const NormalCloud& object, const Plane& table, const CubeParams& params,
                 const SilhouetteSmear& smear = {});

// The minimum-volume upright box around the cluster's points: the minimum-area rectangle of
// their footprint on the table times the height of the highest point above it. Type Cube,
// bounding_box == true; ok == false only for fewer than 3 finite points or an invalid table.
ShapeFit boundingBox(const Cloud& cluster, const Plane& table);

// Distance [m] of `point` to the surface of the fitted box `box` (any face, the bottom one too),
// from inside or outside alike.
float distanceToBox(const ShapeFit& box, const Eigen::Vector3f& point);
// Distance [m] of `point` to the faces of that box the camera (at the origin) sees. A point
// behind them (seen through the box) or beside a box too small is far from them.
float distanceToVisibleBoxSurface(const ShapeFit& box, const Eigen::Vector3f& point);
// The same for every point of `points` (the box's frame and visible faces worked out once).
void distancesToVisibleBoxSurface(const ShapeFit& box, const NormalCloud& points,
                                  std::vector<float>& distances);

// Value below which `fraction` of the (non-empty) `values` lie (partially sorts `values`).
float quantile(std::vector<float>& values, float fraction);

}  // namespace tabletop_shapes
