// §3: smoothing and normals by moving least squares.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

using NormalCloud = pcl::PointCloud<pcl::PointNormal>;

// Normals are oriented towards the viewpoint (the cloud frame's origin, i.e. the camera).
// Points whose normal cannot be computed are dropped; `out` is dense.
void estimateNormalsMLS(const CloudConstPtr& cluster, const NormalParams& params, NormalCloud& out);

// MLS's local plane: pcl::compute3DCentroid and pcl::computeCovarianceMatrix of the points
// `indices` (finite) of `cloud`, on pairs of doubles: each entry is the same sum of the same
// products in the same order as PCL's loops, so the same doubles, in about half the instructions.
void centroidAndCovariance(const Cloud& cloud, const std::vector<int>& indices,
                           Eigen::Vector4d& centroid, Eigen::Matrix3d& covariance);

}  // namespace tabletop_shapes
