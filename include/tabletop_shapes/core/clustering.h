// §2.5 Euclidean cluster extraction with a k-d tree.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

// Clusters sorted by size, largest first; each is a new dense cloud with the input's header.
std::vector<CloudPtr> extractClusters(const CloudConstPtr& cloud, const ClusteringParams& params);

}  // namespace tabletop_shapes
