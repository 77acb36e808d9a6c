// The shape stage after clustering, shared by Pipeline and the shape_estimation nodelet so that
// both run the same steps: each cluster stood on its support (the table, or the object under
// it: support.h), fitted (ShapeEstimator), then bottles split at the neck rejoined (neck_join.h).
#pragma once

#include "tabletop_shapes/core/shape_estimator.h"

namespace tabletop_shapes {

// One fit per object, in the order of `clusters`; a rejoined neck's cluster is merged into its
// body's, so `clusters` is updated to stay in step with the fits.
std::vector<ShapeFit> fitObjects(const ShapeEstimator& estimator, const Plane& table,
                                 const ViewBounds& view, std::vector<CloudPtr>& clusters);

}  // namespace tabletop_shapes
