// tabletop_shapes/Preprocess (paper 2.1): any sensor_msgs/PointCloud2 with float32 x y z (rgb
// optional; a driver, a bag, another camera) -> range-limited, voxel-downsampled XYZ cloud.
// Subscribes: input (sensor_msgs/PointCloud2, read as x y z; an XYZRGB cloud of a nodelet in
//             the same manager, such as OpenNI2Driver's, arrives without a copy: see
//             ros/cloud_input.h)
// Publishes:  preprocessed (pcl::PointCloud<pcl::PointXYZ>, shared with the next nodelet;
//             header.seq numbers the frames, so that the next stage counts the ones it drops)
//             view (tabletop_shapes/View, same stamp): the bounds of the input's valid pixels,
//             which ShapeEstimation needs to flag objects cut by the image border (the
//             voxel grid leaves an unorganised cloud)
//             objects (tabletop_shapes/Objects) for a frame skipped here, with the reason;
//             also for a frame refused because the chain is busy ("skipped: chain busy ...")
// Admission: a frame is taken in only while fewer than ~max_frames_in_flight frames are
//   between here and the chain's `objects` output, which this nodelet also subscribes to
//   (the answers' stamps free their places; stages in the same manager free them before
//   publishing: ros/frame_admission.h). Others are answered at
//   once on `objects` and counted as `frames skipped: chain busy` on /diagnostics.
// Parameters: cfg/Preprocess.cfg (dynamic_reconfigure, with max_frames_in_flight and
//             in_flight_timeout); ~queue_size (int, 4);
//             ~max_points (int, 4000000): larger clouds are skipped with a warning.
#include "tabletop_shapes/core/pcd_reader.h"
#include "tabletop_shapes/core/preprocess.h"
#include "tabletop_shapes/ros/answer_publisher.h"
#include "tabletop_shapes/ros/cloud_input.h"
#include "tabletop_shapes/ros/frame_admission.h"
#include "tabletop_shapes/ros/conversions.h"
#include "tabletop_shapes/ros/reconfigure.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/PreprocessConfig.h"

#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>

#include <iomanip>
#include <memory>
#include <mutex>
#include <sstream>

namespace tabletop_shapes {

class PreprocessNodelet : public nodelet::Nodelet {
 public:
  ~PreprocessNodelet() override {
    if (!answers_topic_.empty()) bridge::unregisterAdmission(answers_topic_, &admission_);
  }

 private:
  void onInit() override {
    ros::NodeHandle& node = getNodeHandle();
    ros::NodeHandle& private_node = getPrivateNodeHandle();
    // Start-up values are checked before anything holds the nodelet's callback queues: the
    // loader destroys a nodelet whose onInit throws after those queues, and a live timer or
    // subscriber then crashes the process before the refusal is printed.
    bridge::seedCoreDefaults(private_node, {"preprocess"});
    bridge::checkChainParameters<PreprocessConfig>(private_node);
    monitor_ = std::make_unique<bridge::StageMonitor>(node, getName());
    reconfigure_ = std::make_unique<dynamic_reconfigure::Server<PreprocessConfig>>(
        reconfigure_mutex_, private_node);
    reconfigure_->setCallback([this](PreprocessConfig& config, uint32_t) {
      PipelineParams params;
      std::string error;
      if (!bridge::applyConfig(config, {"preprocess"}, params, error)) {
        NODELET_ERROR("rejected parameters: %s", error.c_str());
        return;
      }
      admission_.setLimits(static_cast<size_t>(config.max_frames_in_flight),
                           config.in_flight_timeout);
      std::lock_guard<std::mutex> lock(params_mutex_);
      params_ = params.preprocess;
    });
    publisher_ = node.advertise<Cloud>("preprocessed", 1);
    view_publisher_ = node.advertise<View>("view", 5);
    skipped_publisher_ = bridge::advertiseAnswers(node);
    // Deeper than one: a frame that comes while the last one is read or preprocessed waits
    // here and is answered (admitted or "chain busy"); roscpp drops an overflow unanswered.
    const int queue_size = private_node.param("queue_size", 4);
    const int max_points = private_node.param("max_points", static_cast<int>(kDefaultMaxPoints));
    if (max_points < 1) {
      NODELET_ERROR("~max_points must be positive, got %d; using %d", max_points,
                    static_cast<int>(kDefaultMaxPoints));
    }
    max_points_ = max_points < 1 ? kDefaultMaxPoints : static_cast<uint64_t>(max_points);
    bridge::InputCloudCallbacks callbacks;
    callbacks.on_shared = [this](const auto& cloud) { onCloud(cloud); };
    callbacks.on_received = [this](const auto& cloud) { onCloud(cloud); };
    callbacks.on_invalid = [this](const std_msgs::Header& header, const std::string& invalid) {
      skip(header, invalid);
    };
    callbacks.admit = [this](const std_msgs::Header& header) { return admit(header); };
    subscriber_ = bridge::subscribeInputCloud(node, "input", queue_size, callbacks, max_points_);
    monitor_->expectInput<sensor_msgs::PointCloud2>(subscriber_);
    // The chain's answers free places in flight: on the multi-threaded handle, so that an
    // answer is not held up behind a frame this nodelet is preprocessing. By pointer in the
    // same manager (no copy); the queue is deep because missing one costs the timeout.
    answers_subscriber_ =
        getMTNodeHandle().subscribe("objects", 50, &PreprocessNodelet::onAnswer, this);
    // Stages in this manager free a frame's place before they publish its answer; the topic
    // still brings the answers of stages in other processes.
    answers_topic_ = answers_subscriber_.getTopic();
    bridge::registerAdmission(answers_topic_, &admission_);
  }

  void onAnswer(const ObjectsConstPtr& objects) {
    // A busy answer is for a frame never admitted, though its stamp may repeat one in flight.
    if (bridge::isChainBusyReason(objects->reason)) return;
    admission_.answered(bridge::FrameAdmission::stampMicroseconds(objects->header.stamp.toNSec()));
  }

  // Admits the frame while the chain has room, else answers it as busy. A frame in flight
  // whose answer never came is given up here, with a throttled warning. Called before a
  // PointCloud2's points are read, and before onCloud for a cloud handed over by pointer.
  bool admit(const std_msgs::Header& header) {
    const bridge::FrameAdmission::Decision decision =
        admission_.admit(bridge::FrameAdmission::stampMicroseconds(header.stamp.toNSec()),
                         bridge::FrameAdmission::Clock::now());
    if (!decision.timed_out_stamps_us.empty()) {
      std::ostringstream text;
      text << decision.timed_out_stamps_us.size() << " frame(s) in flight had no objects message "
           << "within in_flight_timeout (the last stamped "
           << decision.timed_out_stamps_us.back() / 1000000 << "." << std::setw(6)
           << std::setfill('0') << decision.timed_out_stamps_us.back() % 1000000
           << "): a later stage died or dropped it; admitting frames again";
      monitor_->log({bridge::Problem::Level::Warn, text.str(), "in_flight_timeout"});
    }
    if (decision.admitted) return true;
    monitor_->countSequence(header.seq);  // numbered too: a refused frame is no gap
    monitor_->frameSkippedBusy();
    skipped_publisher_.publish(
        bridge::skippedFrameObjects(header, bridge::chainBusyReason(decision.in_flight)));
    return false;
  }

  // A frame without output: reported, and answered on `objects` so that a consumer waiting
  // there hears of every frame.
  void skip(const std_msgs::Header& header, const std::string& reason) {
    monitor_->frameSkipped(reason,
                           {bridge::Problem::Level::Error, "skipping input cloud: " + reason, {}});
    bridge::publishAnswer(skipped_publisher_,
                          bridge::skippedFrameObjects(header, "invalid cloud: " + reason));
  }

  // The driver's XYZRGB cloud by pointer, or a PointCloud2 read as XYZ.
  template <typename PointT>
  void onCloud(const boost::shared_ptr<const pcl::PointCloud<PointT>>& input) {
    const bridge::Stopwatch stopwatch;
    monitor_->countInput(input.get());
    monitor_->countSequence(input->header.seq);
    if (input->size() > max_points_) {  // a cloud handed over by pointer was not checked yet
      skip(pcl_conversions::fromPCL(input->header), std::to_string(input->size()) +
                                                        " points is above max_points " +
                                                        std::to_string(max_points_));
      return;
    }
    {
      std::lock_guard<std::mutex> lock(params_mutex_);
      preprocessor_.setParams(params_);  // a reconfigured value applies from this frame on
    }
    auto output = boost::make_shared<Cloud>();
    ViewBounds view;  // from the preprocessing's own pass over the image
    preprocessor_.apply(*input, *output, &view);
    view.point_spacing = preprocessor_.params().leaf_size;
    const size_t points_out = output->size();
    if (points_out == 0) {  // still published: every frame gets its (empty) answer downstream
      const std::string reason = input->empty()
                                     ? "input cloud is empty"
                                     : "none of the " + std::to_string(input->size()) +
                                           " input points is finite and within max_range";
      monitor_->frameWithoutResult(reason, {bridge::Problem::Level::Warn, reason, {}});
    }
    output->header.seq = ++published_;
    // The view first: it reaches ShapeEstimation before the frame's clusters do.
    view_publisher_.publish(boost::shared_ptr<const View>(boost::make_shared<View>(
        bridge::toViewMsg(view, pcl_conversions::fromPCL(output->header)))));
    boost::shared_ptr<const Cloud> shared = output;
    bridge::markPublished(shared);
    publisher_.publish(shared);
    monitor_->frameDone(stopwatch.milliseconds(), input->size(), points_out);
  }

  std::unique_ptr<bridge::StageMonitor> monitor_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<PreprocessConfig>> reconfigure_;
  std::mutex params_mutex_;
  PreprocessParams params_;
  Preprocessor preprocessor_;  // keeps its buffers between frames
  uint64_t max_points_ = kDefaultMaxPoints;
  uint32_t published_ = 0;  // frames published: the seq of the next stage's input
  // Limits set by the reconfigure callback, which runs before the first frame.
  bridge::FrameAdmission admission_{1, 2.0};
  std::string answers_topic_;  // where admission_ is registered (empty: not yet)
  ros::Publisher publisher_, view_publisher_, skipped_publisher_;
  ros::Subscriber subscriber_, answers_subscriber_;
};

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::PreprocessNodelet, nodelet::Nodelet)
