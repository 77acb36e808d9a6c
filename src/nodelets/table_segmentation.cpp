// tabletop_shapes/TableSegmentation (paper 2.2-2.4): the support plane, its hull and the
// object points above it.
// Subscribes: preprocessed (pcl::PointCloud<pcl::PointXYZ>)
// Publishes, once per processed frame and with the same stamp (the PCL header's, in whole
// microseconds), so that the next stages pair them exactly:
//   table (tabletop_shapes/Table; inliers == 0 when no table was found; with the depth noise,
//     hull_margin and viewpoint that ShapeEstimation's table-edge rule needs)
//   objects_cloud (pcl::PointCloud<pcl::PointXYZ>; empty when no table was found)
//   table_inliers (pcl::PointCloud<pcl::PointXYZ>), only while someone subscribes
//   objects (tabletop_shapes/Objects) for a frame skipped here (no up transform), with the reason
// The objects cloud's header.seq numbers the frames published, so that Clustering counts the
// frames it drops.
// Parameters: cfg/TableSegmentation.cfg (dynamic_reconfigure), and "up" (at most one of):
//   ~up_frame (string, ""): a frame whose +z is up (e.g. base_link), looked up with tf2 at the
//     cloud's own stamp; a missing transform skips the frame with a throttled warning; stamps
//     going back (a looped bag) are warned about (ros/frame_transforms.h)
//   ~up (string "auto", "X,Y,Z" or "[x, y, z]", or a list of 3 numbers; default auto): up in
//     the cloud frame, or auto: estimated from the scene in every frame
//   ~auto_up (bool, false): the older spelling of up: auto
//   Neither given: auto. A malformed or contradictory value fails the nodelet's load. A given up
//   (or up_frame) is compared with the scene's up once a second: off by more than
//   up_tolerance_deg, a WARN on /diagnostics and in the log names the angle.
//   ~tf_timeout (double, 0.1 s): how long to wait for the transform
//   ~queue_size (int, 1)
#include "tabletop_shapes/core/table_segmentation.h"
#include "tabletop_shapes/core/up_direction.h"
#include "tabletop_shapes/ros/answer_publisher.h"
#include "tabletop_shapes/ros/conversions.h"
#include "tabletop_shapes/ros/frame_transforms.h"
#include "tabletop_shapes/ros/reconfigure.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/TableSegmentationConfig.h"

#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>

namespace tabletop_shapes {

class TableSegmentationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& node = getNodeHandle();
    ros::NodeHandle& private_node = getPrivateNodeHandle();
    // Start-up values are checked before anything holds the nodelet's callback queues: the
    // loader destroys a nodelet whose onInit throws after those queues, and a live timer or
    // subscriber then crashes the process before the refusal is printed.
    bridge::seedCoreDefaults(private_node, {"table"});
    up_frame_ = private_node.param<std::string>("up_frame", "");
    const ros::Duration tf_timeout(private_node.param("tf_timeout", 0.1));
    try {
      up_ = readUpSetting(private_node);
    } catch (const std::invalid_argument& error) {
      // Thrown on: the load fails and the loader exits, instead of running with a wrong up.
      NODELET_FATAL("%s", error.what());
      throw;
    }
    monitor_ = std::make_unique<bridge::StageMonitor>(node, getName());
    const std::string up_source = !up_frame_.empty() ? "+z of frame " + up_frame_
                                  : up_.automatic    ? "estimated from the scene in every frame"
                                                     : formatUp(up_.vector) + " in the cloud frame";
    NODELET_INFO("up: %s", up_source.c_str());
    if (!up_frame_.empty()) {
      transforms_ =
          std::make_unique<bridge::FrameTransforms>(tf_timeout, bridge::warnThrough(*monitor_));
      transforms_->listen(node);
    }

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
    skipped_publisher_ = bridge::advertiseAnswers(node);
    const int queue_size = private_node.param("queue_size", 1);
    subscriber_ =
        node.subscribe("preprocessed", queue_size, &TableSegmentationNodelet::onCloud, this);
    monitor_->expectInput<Cloud>(subscriber_);
  }

  // ~up as text or a list of numbers, one syntax with the command's --up (core parseUp), and
  // ~auto_up; throws std::invalid_argument naming the parameter for a malformed or
  // contradictory value.
  UpSetting readUpSetting(ros::NodeHandle& private_node) const {
    std::string text;
    XmlRpc::XmlRpcValue value;
    if (private_node.getParam("up", value)) {
      if (value.getType() == XmlRpc::XmlRpcValue::TypeString) {
        text = static_cast<std::string>(value);
      } else if (value.getType() == XmlRpc::XmlRpcValue::TypeArray) {
        std::ostringstream list;
        list << "[";
        for (int i = 0; i < value.size(); ++i) {
          const auto type = value[i].getType();
          list << (i ? ", " : "");
          if (type == XmlRpc::XmlRpcValue::TypeDouble) {
            list << static_cast<double>(value[i]);
          } else if (type == XmlRpc::XmlRpcValue::TypeInt) {
            list << static_cast<int>(value[i]);
          } else {
            list << value[i].toXml();
          }
        }
        list << "]";
        text = list.str();
      } else {
        text = value.toXml();
      }
    }
    UpSetting up;
    std::string error;
    const std::string where = private_node.resolveName("up");
    if (!parseUp(text, up, error)) throw std::invalid_argument(where + ": " + error);
    if (private_node.param("auto_up", false)) {
      if (!up.automatic) {
        throw std::invalid_argument(where + " is " + text + " but " +
                                    private_node.resolveName("auto_up") + " is true: give one");
      }
    }
    if (!up_frame_.empty() && !up.automatic) {
      throw std::invalid_argument(where + " is " + text + " and " +
                                  private_node.resolveName("up_frame") + " is " + up_frame_ +
                                  ": give one of them");
    }
    return up;
  }

  // A given up in the cloud frame (parameter or tf); false (frame skipped) when the transform
  // is missing.
  bool lookUpDirection(const CloudConstPtr& cloud, TableParams& params) {
    if (up_frame_.empty()) {
      params.up = up_.vector;
      return true;
    }
    const std_msgs::Header header = pcl_conversions::fromPCL(cloud->header);
    try {
      const Eigen::Isometry3d cloud_from_up =
          transforms_->lookup(header.frame_id, up_frame_, header.stamp);
      params.up = (cloud_from_up.linear() * Eigen::Vector3d::UnitZ()).cast<float>();
      return true;
    } catch (const tf2::TransformException& error) {
      const std::string reason = "no transform from up_frame '" + up_frame_ + "' to '" +
                                 header.frame_id + "': " + error.what();
      // tf's text holds times: throttle on the frames, not on the whole text.
      monitor_->frameSkipped(reason, {bridge::Problem::Level::Warn, "skipping frame: " + reason,
                                      "no transform from " + up_frame_});
      bridge::publishAnswer(skipped_publisher_, bridge::skippedFrameObjects(header, reason));
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
    TableResult result;
    const bool up_given = !(up_frame_.empty() && up_.automatic);
    if (!up_given) {
      up_estimate_.segment(input, params, result);
    } else {
      if (!lookUpDirection(input, params)) return;
      result = TableSegmenter(params).segment(input);
    }
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
    // By pointer: Clustering and ShapeEstimation in the same manager take it without a copy.
    const boost::shared_ptr<const Table> table = boost::make_shared<Table>(
        bridge::toTableMsg(result, params.hull_margin, input->sensor_origin_.head<3>(), header));
    table_publisher_.publish(table);
    publishCloud(objects_publisher_, objects);
    monitor_->frameDone(stopwatch.milliseconds(), cloud->size(), objects->size());
    // After the frame's outputs: the check is a plane search of its own (once a second), which
    // the next stages need not wait for.
    if (up_given) checkUp(input, params, result);
  }

  // A given up (parameter or tf) against the scene's, at most once a second: it costs a plane
  // search. (An estimated up is the scene's by construction and is not checked.)
  void checkUp(const CloudConstPtr& cloud, const TableParams& params, const TableResult& table) {
    const ros::WallTime now = ros::WallTime::now();
    if (now < next_up_check_) return;
    next_up_check_ = now + ros::WallDuration(1.0);
    const UpCheck check = checkUpAgainstScene(cloud, params, table);
    monitor_->setWarning("up", check.warning);
  }

  static void publishCloud(ros::Publisher& publisher, const boost::shared_ptr<Cloud>& cloud) {
    boost::shared_ptr<const Cloud> shared = cloud;
    bridge::markPublished(shared);
    publisher.publish(shared);
  }

  std::unique_ptr<bridge::StageMonitor> monitor_;
  std::string up_frame_;
  UpSetting up_;            // used when up_frame_ is empty
  UpEstimate up_estimate_;  // up: auto, held between frames
  ros::WallTime next_up_check_;
  std::unique_ptr<bridge::FrameTransforms> transforms_;  // with up_frame only
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
