// A bottle's neck cut off its body (beyond the paper): the split (cluster_split.h) parts a
// neck from the shoulder at their concave seam, and supportPlanes (support.h) stands it on the
// shoulder as if stacked. Run after fitting.
#pragma once

#include "tabletop_shapes/core/shape_estimator.h"

namespace tabletop_shapes {

// Joins every fitted solid resting above the table that is narrower than a round solid under
// it, on that one's axis and starting at its top, to it, when the joined cluster fits a round
// solid (on the lower one's support): the cluster, support and fit of the lower one are
// replaced, the neck's removed. `clusters`, `supports` and `fits` are in the same order.
void rejoinNecks(const ShapeEstimator& estimator, const Plane& table, const ViewBounds& view,
                 std::vector<CloudPtr>& clusters, std::vector<Plane>& supports,
                 std::vector<ShapeFit>& fits);

}  // namespace tabletop_shapes
