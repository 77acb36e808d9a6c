// tabletop_shapes/Preprocess (paper 2.1): any sensor_msgs/PointCloud2 with float32 x y z (rgb
// optional; a driver, a bag, another camera) -> range-limited, voxel-downsampled XYZ cloud.
// Subscribes: input (sensor_msgs/PointCloud2)
// Publishes:  preprocessed (pcl::PointCloud<pcl::PointXYZ>, shared with the next nodelet)
// Parameters: cfg/Preprocess.cfg (dynamic_reconfigure); ~queue_size (int, 1).
#include "tabletop_shapes/core/preprocess.h"
#include "tabletop_shapes/ros/reconfigure.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/PreprocessConfig.h"

#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <memory>
#include <mutex>

namespace tabletop_shapes {

namespace {

// Empty when the cloud can be read as x y z floats, else why not.
std::string invalidCloudReason(const sensor_msgs::PointCloud2& msg) {
  for (const char* axis : {"x", "y", "z"}) {
    const auto field =
        std::find_if(msg.fields.begin(), msg.fields.end(),
                     [&](const sensor_msgs::PointField& f) { return f.name == axis; });
    if (field == msg.fields.end()) return std::string("no field '") + axis + "'";
    if (field->datatype != sensor_msgs::PointField::FLOAT32) {
      return std::string("field '") + axis + "' is not FLOAT32";
    }
    if (field->offset + 4 > msg.point_step) return std::string("field '") + axis + "' overflows";
  }
  if (static_cast<uint64_t>(msg.row_step) * msg.height > msg.data.size() ||
      static_cast<uint64_t>(msg.point_step) * msg.width > msg.row_step) {
    return "data shorter than width x height x point_step";
  }
  return "";
}

}  // namespace

class PreprocessNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& node = getNodeHandle();
    ros::NodeHandle& private_node = getPrivateNodeHandle();
    monitor_ = std::make_unique<bridge::StageMonitor>(node, getName());
    bridge::seedCoreDefaults(private_node, {"preprocess"});
    reconfigure_ = std::make_unique<dynamic_reconfigure::Server<PreprocessConfig>>(
        reconfigure_mutex_, private_node);
    reconfigure_->setCallback([this](PreprocessConfig& config, uint32_t) {
      PipelineParams params;
      std::string error;
      if (!bridge::applyConfig(config, {"preprocess"}, params, error)) {
        NODELET_ERROR("rejected parameters: %s", error.c_str());
        return;
      }
      std::lock_guard<std::mutex> lock(params_mutex_);
      params_ = params.preprocess;
    });
    publisher_ = node.advertise<Cloud>("preprocessed", 1);
    const int queue_size = private_node.param("queue_size", 1);
    subscriber_ = node.subscribe("input", queue_size, &PreprocessNodelet::onCloud, this);
  }

  void onCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    const bridge::Stopwatch stopwatch;
    const std::string invalid = invalidCloudReason(*msg);
    if (!invalid.empty()) {
      NODELET_ERROR_THROTTLE(5.0, "skipping input cloud: %s", invalid.c_str());
      monitor_->frameSkipped(invalid);
      return;
    }
    {
      std::lock_guard<std::mutex> lock(params_mutex_);
      preprocessor_.setParams(params_);  // a reconfigured value applies from this frame on
    }
    // The only conversion of the chain: the wire format into PCL, x y z only.
    pcl::fromROSMsg(*msg, input_);
    auto output = boost::make_shared<Cloud>();
    preprocessor_.apply(input_, *output);
    output->header = input_.header;
    const size_t points_out = output->size();
    boost::shared_ptr<const Cloud> shared = output;
    bridge::markPublished(shared);
    publisher_.publish(shared);
    monitor_->frameDone(stopwatch.milliseconds(), msg->width * msg->height, points_out);
  }

  std::unique_ptr<bridge::StageMonitor> monitor_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<PreprocessConfig>> reconfigure_;
  std::mutex params_mutex_;
  PreprocessParams params_;
  Preprocessor preprocessor_;  // keeps its buffers between frames
  pcl::PointCloud<pcl::PointXYZ> input_;
  ros::Publisher publisher_;
  ros::Subscriber subscriber_;
};

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::PreprocessNodelet, nodelet::Nodelet)
