// tabletop_shapes/LatencyProbe: the clock of `make benchmark-speed`. Loaded into the manager of
// the chain it measures, it subscribes to the chain's topics with their own types (so clouds
// reach it by pointer, without a copy or serialisation that would slow the chain down) and
// writes one CSV line per message: topic, the message's stamp and the wall time it arrived, both
// in microseconds, its size (points of a cloud, fitted objects of an Objects message, hull
// points of a Table) and, for an Objects message, what answers the frame: "result" (no reason),
// "busy" (refused by Preprocess's admission: "skipped: chain busy ...") or "reason" (skipped or
// no table); empty for other topics. The feeder (or the camera driver) stamps each cloud with the
// wall time it publishes (captures) it, so arrival minus stamp is the latency from the input to
// that stage's output. Parameters: ~output (CSV path), ~topics (comma-separated "name:type", type
// one of xyz, xyzl,
//   xyzrgb, table, objects, pc2; names resolved in the nodelet's namespace).
#include "tabletop_shapes/Objects.h"
#include "tabletop_shapes/Table.h"
#include "tabletop_shapes/ros/frame_admission.h"

#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/spinner.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>
#include <sensor_msgs/PointCloud2.h>

#include <cinttypes>
#include <cstdio>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

namespace tabletop_shapes {

class LatencyProbeNodelet : public nodelet::Nodelet {
 public:
  ~LatencyProbeNodelet() override {
    subscribers_.clear();
    if (spinner_) spinner_->stop();
    if (file_) std::fclose(file_);
  }

 private:
  void onInit() override {
    // A queue and a thread of its own: the manager's workers are busy with the chain, and a
    // message waiting for one of them would be logged late (a latency the chain did not have)
    // and, for the camera's 10 MB clouds, held in memory meanwhile.
    ros::NodeHandle node(getNodeHandle());
    node.setCallbackQueue(&queue_);
    spinner_ = std::make_unique<ros::AsyncSpinner>(1, &queue_);
    ros::NodeHandle& private_node = getPrivateNodeHandle();
    const std::string output = private_node.param<std::string>("output", "latency.csv");
    file_ = std::fopen(output.c_str(), "w");
    if (!file_) {
      NODELET_ERROR("cannot write %s", output.c_str());
      return;
    }
    std::fprintf(file_, "topic,stamp_us,arrival_us,size,answer\n");
    std::fflush(file_);
    // One string: a list on the `nodelet load` command line does not reach the nodelet.
    std::vector<std::string> topics;
    std::stringstream list(private_node.param<std::string>("topics", ""));
    for (std::string entry; std::getline(list, entry, ',');) {
      if (!entry.empty()) topics.push_back(entry);
    }
    for (const std::string& entry : topics) {
      const size_t colon = entry.rfind(':');
      const std::string name = entry.substr(0, colon);
      const std::string type = colon == std::string::npos ? "" : entry.substr(colon + 1);
      const auto pcl_stamp = [](const auto& m) { return pcl_conversions::fromPCL(m.header).stamp; };
      const auto pcl_size = [](const auto& m) { return m.size(); };
      const auto msg_stamp = [](const auto& m) { return m.header.stamp; };
      const auto no_answer = [](const auto&) { return ""; };
      if (type == "xyz") {
        subscribe<pcl::PointCloud<pcl::PointXYZ>>(node, name, pcl_stamp, pcl_size, no_answer);
      } else if (type == "xyzl") {
        subscribe<pcl::PointCloud<pcl::PointXYZL>>(node, name, pcl_stamp, pcl_size, no_answer);
      } else if (type == "xyzrgb") {
        subscribe<pcl::PointCloud<pcl::PointXYZRGB>>(node, name, pcl_stamp, pcl_size, no_answer);
      } else if (type == "table") {
        subscribe<Table>(
            node, name, msg_stamp, [](const Table& m) { return m.hull.points.size(); }, no_answer);
      } else if (type == "objects") {
        subscribe<Objects>(
            node, name, msg_stamp,
            [](const Objects& m) { return m.cubes.size() + m.cylinders.size() + m.cones.size(); },
            [](const Objects& m) {
              return m.reason.empty()                      ? "result"
                     : bridge::isChainBusyReason(m.reason) ? "busy"
                                                           : "reason";
            });
      } else if (type == "pc2") {
        subscribe<sensor_msgs::PointCloud2>(
            node, name, msg_stamp,
            [](const sensor_msgs::PointCloud2& m) {
              return static_cast<size_t>(m.width) * m.height;
            },
            no_answer);
      } else {
        NODELET_ERROR(
            "topic entry '%s': expected name:type with type xyz, xyzl, xyzrgb, table, "
            "objects or pc2",
            entry.c_str());
      }
    }
    spinner_->start();
  }

  template <typename Message, typename StampOf, typename SizeOf, typename AnswerOf>
  void subscribe(ros::NodeHandle& node, const std::string& name, StampOf stamp_of, SizeOf size_of,
                 AnswerOf answer_of) {
    const std::string resolved = node.resolveName(name);
    subscribers_.push_back(node.subscribe<Message>(
        name, 50,
        [this, resolved, stamp_of, size_of,
         answer_of](const boost::shared_ptr<const Message>& message) {
          const int64_t arrival = ros::WallTime::now().toNSec() / 1000;
          const int64_t stamp = stamp_of(*message).toNSec() / 1000;
          const size_t size = size_of(*message);
          const char* answer = answer_of(*message);
          std::lock_guard<std::mutex> lock(mutex_);
          std::fprintf(file_, "%s,%" PRId64 ",%" PRId64 ",%zu,%s\n", resolved.c_str(), stamp,
                       arrival, size, answer);
          std::fflush(file_);  // the manager may be killed at the end of a run
        }));
  }

  ros::CallbackQueue queue_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  FILE* file_ = nullptr;
  std::mutex mutex_;
  std::vector<ros::Subscriber> subscribers_;
};

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::LatencyProbeNodelet, nodelet::Nodelet)
