// A can seen partly in a crowd (issue 15): its neighbours hide most of its wall, so the round
// fit rests on too few wall points and the box around its points wins. Its top still shows a
// round outline. This tells a lid from a box's top face by the outline of the top points.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

// The outline of a box's top points (those within 1 cm of its top) as seen from above, and how
// well a circle and the box's own top face explain it.
struct TopOutline {
  int points = 0;          // outline points: the farthest top point in each direction
  int on_circle = 0;       // of them within the band of the best circle through them
  int on_box_edges = 0;    // of them within the band of the box's top face edges
  float arc_deg = 0.0f;    // the arc of the circle its points cover
  float outside = 1.0f;    // share of the cluster's points beyond the circle (+ tolerance)
  float above = 1.0f;      // share of the cluster's points over the box's top (+ 1 cm)
  Eigen::Vector2f center;  // the circle, in the box's x / y frame from its centre [m]
  float radius = 0.0f;     // [m]
  // hiddenLidOutline only: the side away from the camera, which a neighbour in front cannot hide.
  float far_share = 0.0f;       // share of the outline points there that lie on the circle
  float far_overhang = 1.0f;    // how far the circle's far half reaches beyond the footprint [m]
  float far_corner_gap = 0.0f;  // distance of the box's two far top corners to the points [m]
};

// The outline of the top points of `cluster` under the upright `box` fitted to it, with the best
// circle (most outline points within its band, radius `min_radius`-`max_radius`) and the share
// of the points farther than `tolerance` beyond it. `points` is 0 with too few top points.
TopOutline topOutline(const ShapeFit& box, const Cloud& cluster, float min_radius, float max_radius,
                      float tolerance);

// The same outline with the circle that holds all of it (at most one outline point beyond it),
// for a lid cut by a taller neighbour in front, and its far side from the camera (the origin of
// the cluster's frame) described. `points` is 0 when the box's far top corners are not empty
// (kFarCornerGap): no circle is searched then.
TopOutline hiddenLidOutline(const ShapeFit& box, const Cloud& cluster, float min_radius,
                            float max_radius, float tolerance);

// True when the outline is a lid's: most of it on the circle, clearly more than on the box's
// edges, around more than a half turn, with the cluster's points inside the circle and under
// the top.
bool isRoundLid(const TopOutline& outline);

// True when the outline of hiddenLidOutline is a lid's partly hidden from the camera: the rim on
// the far side lies on the circle, the circle stays within the box there, the box's far top
// corners are empty, and the cluster's points lie inside the circle and under the top.
bool isPartlyHiddenLid(const TopOutline& outline);

// The upright cylinder under the lid of `outline`: its circle, from the table (the box's bottom)
// to the box's top.
ShapeFit cylinderUnderLid(const ShapeFit& box, const TopOutline& outline);

}  // namespace tabletop_shapes
