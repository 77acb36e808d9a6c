// Joining the clusters of one open object (beyond the paper): the inside of a bowl, pot or cup,
// seen over the rim, is often a Euclidean cluster apart from the outer wall below the rim (the
// rim joins them only where it is seen from above, and the voxel grid and the sensor's gaps at
// the silhouette cut it). Geometry only (XYZ).
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

// The clusters with every inside joined to the open object it belongs to, largest first. A
// cluster is the inside of another when it reaches up to the other's top (rim) and the lines of
// sight to its points below the rim pass through the other's footprint at the rim's height: the
// camera sees them through the other's opening. In front of a solid object (or under a stacked
// one) the lines of sight to what is visible never cross its top, so solid neighbours and
// stacked objects stay apart. `viewpoint` is the camera position, `table` the support plane.
// `side_by_side`: null or one entry per cluster; clusters with the same number >= 0 stand side
// by side under their own top faces (cluster_split.h) and are never joined to each other (both
// joins). It is updated to follow the joined clusters.
std::vector<CloudPtr> joinInsidesSeenOverRims(std::vector<CloudPtr> clusters, const Plane& table,
                                              const Eigen::Vector3f& viewpoint,
                                              std::vector<int>* side_by_side = nullptr);

// The clusters with the two visible parts of one object hidden in the middle by another joined
// (a box behind a box, a can lying behind one), largest first. Two clusters are joined when
// their tops lie at the same height and every line of sight to the gap between them (sampled
// along the shortest segment from one to the other) meets a third cluster nearer the camera:
// the gap is explained by that occluder. Two objects standing apart show the table or the
// background through the gap between them.
std::vector<CloudPtr> joinPartsHiddenInTheMiddle(std::vector<CloudPtr> clusters, const Plane& table,
                                                 const Eigen::Vector3f& viewpoint,
                                                 std::vector<int>* side_by_side = nullptr);

}  // namespace tabletop_shapes
