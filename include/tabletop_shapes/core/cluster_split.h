// Splitting a Euclidean cluster that holds several touching or stacked objects (beyond the
// paper): surface patches (supervoxels) joined where the surface between them is convex
// (LCCP, Stein et al. 2014); the seam between two touching objects, or between a stacked box
// and the one below, is concave. Geometry only (XYZ).
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

// The cluster's parts, largest first; the cluster itself when it is not split. Parts are kept
// apart only where one rises above the other (stacked or leaning on it, heights from `table`).
std::vector<CloudPtr> splitAtConcaveSeams(const CloudPtr& cluster, const Plane& table,
                                          const ClusteringParams& params);

}  // namespace tabletop_shapes
