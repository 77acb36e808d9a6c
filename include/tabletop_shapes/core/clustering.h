// §2.5 Euclidean cluster extraction with a k-d tree.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

// Clusters sorted by size, largest first; each is a new dense cloud with the input's header.
// Given the table, clusters holding stacked objects are split (cluster_split.h) and the inside
// of an open object is joined to its outer wall (cluster_join.h); the camera is at the cloud's
// sensor origin.
std::vector<CloudPtr> extractClusters(const CloudConstPtr& cloud, const ClusteringParams& params,
                                      const Plane* table = nullptr);

}  // namespace tabletop_shapes
