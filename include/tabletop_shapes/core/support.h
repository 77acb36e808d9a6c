// The plane each object rests on (beyond the paper): the table, or, for an object lying on
// others (a box on a box, a box across two), the table's plane lifted to its own bottom, so that
// its height comes from its bottom face and not from the table under the pile.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

// One plane per cluster, same order, parallel to `table`. A cluster rests on others when its
// lowest points lie more than kMinLift above the table and some of them stand over the
// footprint of another cluster whose top reaches up to them; a cluster whose lower part is only
// hidden (behind an object in front) has nothing under it and keeps the table: its bottom edge
// lies behind that object's footprint as seen from `eye` (the camera, in the clusters' frame),
// and its centre is not over it. A lifted cluster rests on the top face of the objects beneath
// where they show one lower than its own lowest points (the split leaves the seam's rows below).
std::vector<Plane> supportPlanes(const std::vector<CloudPtr>& clusters, const Plane& table,
                                 const Eigen::Vector3f& eye);

}  // namespace tabletop_shapes
