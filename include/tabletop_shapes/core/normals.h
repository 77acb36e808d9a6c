// §3: smoothing and normals by moving least squares.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

using NormalCloud = pcl::PointCloud<pcl::PointNormal>;

// Normals are oriented towards the viewpoint (the cloud frame's origin, i.e. the camera).
// Points whose normal cannot be computed are dropped; `out` is dense.
void estimateNormalsMLS(const CloudConstPtr& cluster, const NormalParams& params, NormalCloud& out);

}  // namespace tabletop_shapes
