// Conversion logic of the ROS layer, apart from the plumbing: core results -> messages, the
// output-frame transform, and the rviz markers. No topics or parameters here.
#pragma once

#include "tabletop_shapes/core/table_edge.h"
#include "tabletop_shapes/core/table_segmentation.h"
#include "tabletop_shapes/core/types.h"
#include "tabletop_shapes/ros/object_messages.h"

#include <Eigen/Geometry>
#include <std_msgs/Header.h>
#include <tabletop_shapes/Objects.h>
#include <tabletop_shapes/Table.h>
#include <tabletop_shapes/View.h>
#include <visualization_msgs/MarkerArray.h>

#include <string>
#include <vector>

namespace tabletop_shapes {
namespace bridge {

// The table message of one frame; inliers == 0 (and no hull) when no table was found, so that
// every frame has one table message to pair the object points with. `hull_margin` is the
// segmentation's (TableParams), `viewpoint` the camera's origin in the header's frame: with the
// table's depth noise they let ShapeEstimation apply the table-edge rule as Pipeline does.
Table toTableMsg(const TableResult& table, float hull_margin, const Eigen::Vector3f& viewpoint,
                 const std_msgs::Header& header);
inline bool tableFound(const Table& table) { return table.inliers > 0; }
Plane planeFromMsg(const Table& table);
std::vector<Eigen::Vector3f> hullFromMsg(const Table& table);

// The chain's step of the core pipeline's table-edge rule (rejectClustersOffTheTable, from the
// table message's plane, hull, depth noise, hull_margin and viewpoint): moves the clusters that
// are no objects on the table from `clusters` to `objects.rejected`, each with its reason.
void rejectClustersOffTheTable(const Table& table, const ViewBounds* view,
                               std::vector<CloudPtr>& clusters, Objects& objects);
// A rejected cluster as the message lists it: centroid, point count, reason.
UnfittedCluster toRejectedMsg(const RejectedCluster& rejected);

// The view of a frame (core ViewBounds) as Preprocess publishes it, and back, so that
// ShapeEstimation flags objects cut by the image border as the core Pipeline does.
View toViewMsg(const ViewBounds& view, const std_msgs::Header& header);
ViewBounds viewFromMsg(const View& msg);

// The objects message of a frame a stage skipped: no table, no objects, the reason.
Objects skippedFrameObjects(const std_msgs::Header& header, const std::string& reason);

// Re-expresses everything in `objects` (poses, table plane, hull and viewpoint, unfitted and
// rejected centroids) in
// `target_frame`, given the transform target <- current frame; every header gets the frame.
void transformObjects(const Eigen::Isometry3d& target_from_source, const std::string& target_frame,
                      Objects& objects);

// The markers of one frame: per object a translucent solid coloured by type (namespace
// "solids") and a label with type and dimensions in cm ("labels"); the table hull as a line
// strip ("table"). Ids 0..n-1 in object order; ids n..previous_count-1 of both namespaces
// are deleted, as is the table strip when there is no table. Returns the object count.
size_t buildMarkers(const Objects& objects, size_t previous_count,
                    visualization_msgs::MarkerArray& markers);

// "cube 15.0 x 9.5 x 5.0 cm" and the like.
std::string labelText(const Cube& cube);
std::string labelText(const Cylinder& cylinder);
std::string labelText(const Cone& cone);

}  // namespace bridge
}  // namespace tabletop_shapes
