// tabletop_shapes/TableSegmentation (paper 2.2-2.4): the support plane, its hull and the
// object points above it.
// Subscribes: preprocessed (pcl::PointCloud<pcl::PointXYZ>)
// Publishes, once per processed frame and with the same stamp (the PCL header's, in whole
// microseconds), so that the next stages pair them exactly:
//   table (tabletop_shapes/Table; inliers == 0 when no table was found)
//   objects_cloud (pcl::PointCloud<pcl::PointXYZ>; empty when no table was found)
//   table_inliers (pcl::PointCloud<pcl::PointXYZ>), only while someone subscribes
//   objects (tabletop_shapes/Objects) for a frame skipped here (no up transform), with the reason
// The objects cloud's header.seq numbers the frames published, so that Clustering counts the
// frames it drops.
// Parameters: cfg/TableSegmentation.cfg (dynamic_reconfigure), and "up":
//   ~up_frame (string, ""): a frame whose +z is up (e.g. base_link), looked up with tf2 at the
//     cloud's stamp; a missing transform skips the frame with a throttled warning
//   ~up (double[3], [0, -1, 0]): up in the cloud frame when ~up_frame is empty
//   ~auto_up (bool, false): estimate up from the scene when ~up_frame is empty
//   ~tf_timeout (double, 0.1 s): how long to wait for the transform
//   ~queue_size (int, 1)
#include "tabletop_shapes/core/table_segmentation.h"
#include "tabletop_shapes/ros/conversions.h"
#include "tabletop_shapes/ros/reconfigure.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/TableSegmentationConfig.h"

#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <memory>
#include <mutex>

namespace tabletop_shapes {

class TableSegmentationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& node = getNodeHandle();
    ros::NodeHandle& private_node = getPrivateNodeHandle();
    monitor_ = std::make_unique<bridge::StageMonitor>(node, getName());

    up_frame_ = private_node.param<std::string>("up_frame", "");
    auto_up_ = private_node.param("auto_up", false);
    tf_timeout_ = ros::Duration(private_node.param("tf_timeout", 0.1));
    std::vector<double> up{0.0, -1.0, 0.0};
    private_node.param("up", up, up);
    if (up.size() != 3 || Eigen::Vector3d(up[0], up[1], up[2]).norm() < 1e-6) {
      NODELET_ERROR("~up must be 3 numbers, not all zero; using [0, -1, 0]");
      up = {0.0, -1.0, 0.0};
    }
    fixed_up_ = Eigen::Vector3f(up[0], up[1], up[2]).normalized();
    if (!up_frame_.empty()) {
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, node);
    }

    bridge::seedCoreDefaults(private_node, {"table"});
    reconfigure_ = std::make_unique<dynamic_reconfigure::Server<TableSegmentationConfig>>(
        reconfigure_mutex_, private_node);
    reconfigure_->setCallback([this](TableSegmentationConfig& config, uint32_t) {
      PipelineParams params;
      std::string error;
      if (!bridge::applyConfig(config, {"table"}, params, error)) {
        NODELET_ERROR("rejected parameters: %s", error.c_str());
        return;
      }
      std::lock_guard<std::mutex> lock(params_mutex_);
      params_ = params.table;
    });

    table_publisher_ = node.advertise<Table>("table", 5);
    objects_publisher_ = node.advertise<Cloud>("objects_cloud", 5);
    inliers_publisher_ = node.advertise<Cloud>("table_inliers", 1);
    skipped_publisher_ = node.advertise<Objects>("objects", 5);
    const int queue_size = private_node.param("queue_size", 1);
    subscriber_ =
        node.subscribe("preprocessed", queue_size, &TableSegmentationNodelet::onCloud, this);
  }

  // Up in the cloud frame; false (frame skipped) when the transform is missing.
  bool lookUpDirection(const CloudConstPtr& cloud, TableParams& params) {
    if (up_frame_.empty()) {
      params.up = fixed_up_;
      if (auto_up_ && !estimateUp(cloud, params, params.up)) params.up = fixed_up_;
      return true;
    }
    const std_msgs::Header header = pcl_conversions::fromPCL(cloud->header);
    try {
      const geometry_msgs::TransformStamped transform =
          tf_buffer_->lookupTransform(header.frame_id, up_frame_, header.stamp, tf_timeout_);
      const auto& q = transform.transform.rotation;
      params.up = (Eigen::Quaternionf(q.w, q.x, q.y, q.z).normalized() * Eigen::Vector3f::UnitZ());
      return true;
    } catch (const tf2::TransformException& error) {
      const std::string reason = "no transform from up_frame '" + up_frame_ + "' to '" +
                                 header.frame_id + "': " + error.what();
      // tf's text holds times: throttle on the frames, not on the whole text.
      monitor_->frameSkipped(reason, {bridge::Problem::Level::Warn, "skipping frame: " + reason,
                                      "no transform from " + up_frame_});
      skipped_publisher_.publish(bridge::skippedFrameObjects(header, reason));
      return false;
    }
  }

  void onCloud(const boost::shared_ptr<const Cloud>& cloud) {
    const bridge::Stopwatch stopwatch;
    monitor_->countInput(cloud.get());
    monitor_->countSequence(cloud->header.seq);
    TableParams params;
    {
      std::lock_guard<std::mutex> lock(params_mutex_);
      params = params_;
    }
    // The core takes std::shared_ptr: share the received cloud, no copy.
    const CloudConstPtr input = pcl::pcl_ptr(cloud);
    if (!lookUpDirection(input, params)) return;
    const TableResult result = TableSegmenter(params).segment(input);
    if (!result.found) {
      monitor_->frameWithoutResult(
          "no table: " + result.reason,
          {bridge::Problem::Level::Warn, "no table in the frame: " + result.reason, {}});
    }

    const std_msgs::Header header = pcl_conversions::fromPCL(cloud->header);
    boost::shared_ptr<Cloud> objects = result.found && result.object_points
                                           ? pcl::ros_ptr(result.object_points)
                                           : boost::make_shared<Cloud>();
    objects->header = cloud->header;
    objects->header.seq = ++published_;
    if (inliers_publisher_.getNumSubscribers() > 0 && result.table_points) {
      boost::shared_ptr<Cloud> inliers = pcl::ros_ptr(result.table_points);
      inliers->header = cloud->header;
      publishCloud(inliers_publisher_, inliers);
    }
    table_publisher_.publish(bridge::toTableMsg(result, header));
    publishCloud(objects_publisher_, objects);
    monitor_->frameDone(stopwatch.milliseconds(), cloud->size(), objects->size());
  }

  static void publishCloud(ros::Publisher& publisher, const boost::shared_ptr<Cloud>& cloud) {
    boost::shared_ptr<const Cloud> shared = cloud;
    bridge::markPublished(shared);
    publisher.publish(shared);
  }

  std::unique_ptr<bridge::StageMonitor> monitor_;
  std::string up_frame_;
  bool auto_up_ = false;
  ros::Duration tf_timeout_;
  Eigen::Vector3f fixed_up_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<TableSegmentationConfig>> reconfigure_;
  std::mutex params_mutex_;
  TableParams params_;
  uint32_t published_ = 0;  // frames published: the seq of Clustering's input
  ros::Publisher table_publisher_, objects_publisher_, inliers_publisher_, skipped_publisher_;
  ros::Subscriber subscriber_;
};

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::TableSegmentationNodelet, nodelet::Nodelet)
