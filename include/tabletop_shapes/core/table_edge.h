// Clusters that rise along the table hull's edge (the foot of a wall behind the table) instead
// of standing on the table.
#pragma once

#include "tabletop_shapes/core/types.h"

#include <string>
#include <vector>

namespace tabletop_shapes {

// A cluster the pipeline does not fit, with why it is not an object on the table.
struct RejectedCluster {
  CloudPtr points;
  std::string reason;
};

// Why `cluster` is no object standing on the table, or "" when it is one.
//
// An object on the table stands over the hull's interior, or hides a part of it from the camera
// (a box cut by the image's border, whose hull edge there is the border itself, hides the table
// behind it). A wall (or a cupboard) behind the table adds the strip of its foot that lies
// within the inlier distance of the plane to the table's inliers, so the hull's edge runs along
// its foot; depth noise and edge bleeding then move some of its points a few centimetres over
// the hull, and the wall up to table.max_height becomes a "slab" cluster, while the camera looks
// past it beyond the hull. Such a cluster is recognised by where its points stand and where
// their lines of sight meet the table: all but a few (under kMinShareBeyondTheBand, the tail
// of the noise and edge bleeding) within the hull's edge band (hull_margin) widened by the
// sensor's depth noise at its range (kEdgeNoiseSigmas standard deviations of the table's own
// noise, which grows with the square of the range), on either side of the hull's edge (the
// table stage also keeps points beyond the hull over a hidden table: the back rows of a mostly
// covered table; outside, noise alone bounds a wall's points), and no point that stands on the
// table beyond the image (`view`, when known: its line of sight meets the table within the hull,
// or it lies outside the hull, and its foot is out of view; a box in the image's corner stands
// where the hull's edge is a chord past it between table points on two borders; without `view`
// every point outside the hull is taken to stand beyond the image's border).
//
// `hull` is the table's convex hull on `table` (ordered), `depth_noise_at_one_metre` the
// table's depth noise scaled to 1 m (TableResult::depth_noise_at_one_metre), `eye` the camera.
std::string whyNotOnTheTable(const Cloud& cluster, const Plane& table,
                             const std::vector<Eigen::Vector3f>& hull,
                             float depth_noise_at_one_metre, float hull_margin,
                             const Eigen::Vector3f& eye, const ViewBounds* view = nullptr);

// Moves the clusters that are no objects on the table (whyNotOnTheTable) from `clusters` to
// `rejected`, keeping the order of the rest.
void rejectClustersOffTheTable(std::vector<CloudPtr>& clusters, const Plane& table,
                               const std::vector<Eigen::Vector3f>& hull,
                               float depth_noise_at_one_metre, float hull_margin,
                               const Eigen::Vector3f& eye, const ViewBounds* view,
                               std::vector<RejectedCluster>& rejected);

}  // namespace tabletop_shapes
