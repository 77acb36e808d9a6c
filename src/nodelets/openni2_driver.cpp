// tabletop_shapes/OpenNI2Driver: an OpenNI2 camera (PrimeSense / Asus Xtion through OpenNI2's
// PS1080 driver, a Kinect v1 through the FreenectDriver plugin, .oni recordings through
// libOniFile) as a nodelet with openni2_camera's topic names:
//   depth/image_raw + depth/camera_info       16UC1, millimetres
//   rgb/image_raw + rgb/camera_info           rgb8
//   depth_registered/points                   organised XYZRGB (XYZ when there is no colour),
//                                             published as a shared pointer: Preprocess in the
//                                             same manager gets an XYZRGB cloud without a copy
//                                             (an XYZ one is copied once)
// The device handling (opening, back-off and throttled messages while it is missing, streams
// only while someone subscribes, closing and reopening a device that fell silent, recording
// checks) is the ROS-free CameraSession (core/camera_session.h) over OpenNI2 (driver/
// openni2_camera.h), unit-tested with a fake device. This nodelet wires: one worker thread
// steps the session, pairs depth and colour frames by timestamp, paces recordings at their
// recorded rate and publishes.
#include "tabletop_shapes/core/camera_session.h"
#include "tabletop_shapes/core/depth_to_cloud.h"
#include "tabletop_shapes/core/playback_schedule.h"
#include "tabletop_shapes/driver/openni2_camera.h"
#include "tabletop_shapes/ros/cloud_pool.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/OpenNI2DriverConfig.h"

#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace tabletop_shapes {
namespace {

using Config = tabletop_shapes::OpenNI2DriverConfig;
using Clock = std::chrono::steady_clock;

// Device time (microseconds) -> ROS time. Live devices: offset = the smallest observed
// (arrival - device time), i.e. the lowest latency, drifting slowly up to follow clock drift.
// Stamps are whole
// microseconds, because PCL headers keep no finer resolution and exact-time synchronisers
// downstream must see the same stamp on the image and on the cloud.
class FrameClock {
 public:
  void reset() { valid_ = false; }
  ros::Time stamp(uint64_t device_us, bool update) {
    const double measured = ros::Time::now().toSec() - device_us * 1e-6;
    if (update) {
      if (!valid_ || device_us < last_device_us_ || std::abs(measured - offset_) > 1.0) {
        offset_ = measured;
      } else if (measured < offset_) {
        offset_ = measured;
      } else {
        offset_ += 0.01 * (measured - offset_);
      }
      valid_ = true;
      last_device_us_ = device_us;
    }
    const double seconds = device_us * 1e-6 + offset_;
    ros::Time time;
    time.fromNSec(static_cast<uint64_t>(std::llround(seconds * 1e6)) * 1000ull);
    return time;
  }

 private:
  bool valid_ = false;
  double offset_ = 0.0;
  uint64_t last_device_us_ = 0;
};

sensor_msgs::CameraInfoPtr cameraInfo(const PinholeIntrinsics& k, const std_msgs::Header& header) {
  auto info = boost::make_shared<sensor_msgs::CameraInfo>();
  info->header = header;
  info->width = static_cast<uint32_t>(k.width);
  info->height = static_cast<uint32_t>(k.height);
  info->distortion_model = "plumb_bob";
  info->D.assign(5, 0.0);
  info->K = {k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0};
  info->R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info->P = {k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  return info;
}

}  // namespace

class OpenNI2DriverNodelet : public nodelet::Nodelet {
 public:
  ~OpenNI2DriverNodelet() override;

 private:
  void onInit() override;
  void reconfigure(Config& config, uint32_t level);
  void run();
  bool sleepUntil(Clock::time_point end);  // false when shutting down
  bool sleepFor(double seconds);
  void log(CameraLogLevel level, const std::string& message);
  bool wantDepth() const;
  bool wantColor() const;
  void handleDepth(const CameraFrame& frame);
  void handleColor(const CameraFrame& frame);
  void publishCloud();
  ros::Time paceRecording(int stream, uint64_t device_us);  // stream: 0 depth, 1 colour

  // parameters
  CameraSessionOptions session_options_;
  std::string depth_frame_id_, rgb_frame_id_;
  bool playback_repeat_ = true;
  std::mutex config_mutex_;
  Config config_;
  bool config_changed_ = false;
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  Config active_;  // the worker's copy

  ros::Publisher depth_image_pub_, depth_info_pub_, rgb_image_pub_, rgb_info_pub_, points_pub_;
  std::thread worker_;
  std::atomic<bool> shutting_down_{false};
  std::unique_ptr<OpenNI2Backend> backend_;

  // frame state (worker thread only); the device itself is the session's
  const CameraDevice* device_ = nullptr;  // while a frame is handled
  FrameClock clock_;
  PinholeIntrinsics depth_intrinsics_;
  // pairing: the last published-worthy frames and their device times
  std::vector<uint16_t> depth_mm_;
  uint64_t depth_us_ = 0;
  ros::Time depth_stamp_;
  bool depth_pending_ = false;
  uint64_t depth_frames_seen_ = 0, color_frames_seen_ = 0;
  // The published clouds, filled again once every subscriber released them (roscpp
  // serialises a remote subscriber's copy inside publish()).
  bridge::CloudPool<pcl::PointXYZRGB> color_clouds_;
  bridge::CloudPool<pcl::PointXYZ> depth_clouds_;
  uint32_t clouds_published_ = 0;  // header.seq: Preprocess counts the clouds it drops
  std::vector<uint8_t> rgb_;
  int rgb_width_ = 0, rgb_height_ = 0;
  uint64_t rgb_us_ = 0;
  bool rgb_valid_ = false;
  bool warned_unregistered_ = false;
  // recording playback schedule: its start on both clocks
  PlaybackSchedule playback_;
  ros::Time playback_origin_stamp_;
  Clock::time_point playback_origin_due_;
  int frame_period_us_ = 33333;
};

OpenNI2DriverNodelet::~OpenNI2DriverNodelet() {
  shutting_down_ = true;
  if (worker_.joinable()) worker_.join();
  reconfigure_server_.reset();
}

void OpenNI2DriverNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  pnh.param<std::string>("device_id", session_options_.device_id, "");
  pnh.param<std::string>("depth_frame_id", depth_frame_id_, "camera_depth_optical_frame");
  pnh.param<std::string>("rgb_frame_id", rgb_frame_id_, "camera_rgb_optical_frame");
  pnh.param("frame_timeout", session_options_.frame_timeout, 3.0);
  pnh.param("reconnect_max_interval", session_options_.reconnect_max_interval, 10.0);
  pnh.param("problem_report_interval", session_options_.problem_report_interval, 10.0);
  pnh.param("playback_repeat", playback_repeat_, true);

  // Lazy: the worker polls the subscriber counts, the callbacks only wake nothing.
  depth_image_pub_ = nh.advertise<sensor_msgs::Image>("depth/image_raw", 2);
  depth_info_pub_ = nh.advertise<sensor_msgs::CameraInfo>("depth/camera_info", 2);
  rgb_image_pub_ = nh.advertise<sensor_msgs::Image>("rgb/image_raw", 2);
  rgb_info_pub_ = nh.advertise<sensor_msgs::CameraInfo>("rgb/camera_info", 2);
  points_pub_ = nh.advertise<pcl::PointCloud<pcl::PointXYZRGB>>("depth_registered/points", 2);

  reconfigure_server_ = std::make_unique<dynamic_reconfigure::Server<Config>>(pnh);
  reconfigure_server_->setCallback(
      [this](Config& config, uint32_t level) { reconfigure(config, level); });

  std::string error;
  backend_ = std::make_unique<OpenNI2Backend>(&error);
  if (!backend_->initialized()) {
    NODELET_ERROR_STREAM(error << "; the camera driver stays idle");
    return;
  }
  const std::string& device_id = session_options_.device_id;
  NODELET_INFO_STREAM("OpenNI2 driver: device_id '"
                      << device_id << "' (" << (device_id.empty() ? "the first device" : "as given")
                      << "); streams start when someone subscribes");
  worker_ = std::thread([this] { run(); });
}

void OpenNI2DriverNodelet::reconfigure(Config& config, uint32_t) {
  std::lock_guard<std::mutex> lock(config_mutex_);
  config_ = config;
  config_changed_ = true;
}

bool OpenNI2DriverNodelet::sleepUntil(Clock::time_point end) {
  // In short steps, so that unloading the nodelet never waits long.
  while (!shutting_down_ && Clock::now() < end) {
    const Clock::duration step = std::chrono::milliseconds(20);
    std::this_thread::sleep_for(std::min(step, end - Clock::now()));
  }
  return !shutting_down_;
}

bool OpenNI2DriverNodelet::sleepFor(double seconds) {
  return sleepUntil(Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                       std::chrono::duration<double>(seconds)));
}

void OpenNI2DriverNodelet::log(CameraLogLevel level, const std::string& message) {
  switch (level) {
    case CameraLogLevel::kInfo:
      NODELET_INFO_STREAM("OpenNI2 camera: " << message);
      break;
    case CameraLogLevel::kWarning:
      NODELET_WARN_STREAM("OpenNI2 camera: " << message);
      break;
    case CameraLogLevel::kError:
      NODELET_ERROR_STREAM("OpenNI2 camera: " << message);
      break;
  }
}

bool OpenNI2DriverNodelet::wantDepth() const {
  return depth_image_pub_.getNumSubscribers() > 0 || depth_info_pub_.getNumSubscribers() > 0 ||
         points_pub_.getNumSubscribers() > 0;
}

bool OpenNI2DriverNodelet::wantColor() const {
  return rgb_image_pub_.getNumSubscribers() > 0 || rgb_info_pub_.getNumSubscribers() > 0 ||
         points_pub_.getNumSubscribers() > 0;
}

ros::Time OpenNI2DriverNodelet::paceRecording(int stream, uint64_t device_us) {
  // Sleep until the frame is due (PlaybackSchedule); the stamp is the scheduled time, the same
  // for depth and colour of one instant, on ROS time as it was when the schedule began.
  if (active_.playback_speed <= 0.0) return ros::Time::now();
  playback_.configure(frame_period_us_, active_.playback_speed);
  const PlaybackSchedule::Slot slot = playback_.schedule(stream, device_us, Clock::now());
  if (slot.restarted) {
    playback_origin_stamp_ =
        ros::Time::now() +
        ros::Duration(std::chrono::duration<double>(slot.due - Clock::now()).count());
    playback_origin_due_ = slot.due;
  }
  sleepUntil(slot.due);
  const double seconds = playback_origin_stamp_.toSec() +
                         std::chrono::duration<double>(slot.due - playback_origin_due_).count();
  ros::Time stamp;
  stamp.fromNSec(static_cast<uint64_t>(std::llround(seconds * 1e6)) * 1000ull);  // whole us
  return stamp;
}

void OpenNI2DriverNodelet::handleDepth(const CameraFrame& frame) {
  const ros::Time stamp = device_->isRecording() ? paceRecording(0, frame.device_us)
                                                 : clock_.stamp(frame.device_us, true);
  if (depth_frames_seen_++ % static_cast<uint64_t>(active_.data_skip + 1) != 0) return;
  const int width = frame.width, height = frame.height;
  const size_t pixels = static_cast<size_t>(width) * height;
  if (frame.bytes < pixels * 2) return;
  const auto* data = static_cast<const uint16_t*>(frame.data);
  depth_mm_.assign(data, data + pixels);
  if (frame.depth_100um) {
    for (uint16_t& z : depth_mm_) z = static_cast<uint16_t>((z + 5) / 10);
  }
  correctDepth(depth_mm_.data(), static_cast<int>(pixels),
               DepthCorrection{active_.z_offset_mm, active_.z_scaling});
  depth_us_ = frame.device_us;
  depth_stamp_ = stamp;

  // The depth image is in the colour camera's frame once registered.
  const bool registered = device_->depthRegisteredToColor();
  PinholeIntrinsics intrinsics = device_->streamInfo(CameraStream::kDepth).intrinsics;
  intrinsics.width = width;
  intrinsics.height = height;
  std_msgs::Header header;
  header.stamp = depth_stamp_;
  header.frame_id = registered ? rgb_frame_id_ : depth_frame_id_;
  if (registered) {
    const CameraStreamInfo color = device_->streamInfo(CameraStream::kColor);
    intrinsics = intrinsicsFromFieldOfView(width, height, color.horizontal_fov, color.vertical_fov);
  } else {
    intrinsics.cx -= active_.depth_ir_offset_x;
    intrinsics.cy -= active_.depth_ir_offset_y;
  }
  depth_intrinsics_ = intrinsics;
  if (depth_image_pub_.getNumSubscribers() > 0) {
    auto image = boost::make_shared<sensor_msgs::Image>();
    image->header = header;
    image->width = static_cast<uint32_t>(width);
    image->height = static_cast<uint32_t>(height);
    image->encoding = "16UC1";
    image->is_bigendian = false;
    image->step = static_cast<uint32_t>(width * 2);
    image->data.resize(pixels * 2);
    std::memcpy(image->data.data(), depth_mm_.data(), image->data.size());
    depth_image_pub_.publish(image);
  }
  if (depth_info_pub_.getNumSubscribers() > 0)
    depth_info_pub_.publish(cameraInfo(intrinsics, header));
  depth_pending_ = true;
  publishCloud();
}

void OpenNI2DriverNodelet::handleColor(const CameraFrame& frame) {
  const ros::Time stamp = device_->isRecording() ? paceRecording(1, frame.device_us)
                                                 : clock_.stamp(frame.device_us, true);
  if (color_frames_seen_++ % static_cast<uint64_t>(active_.data_skip + 1) != 0) return;
  const int width = frame.width, height = frame.height;
  const size_t bytes = static_cast<size_t>(width) * height * 3;
  if (frame.bytes < bytes) return;
  const auto* data = static_cast<const uint8_t*>(frame.data);
  rgb_.assign(data, data + bytes);
  rgb_width_ = width;
  rgb_height_ = height;
  rgb_us_ = frame.device_us;
  rgb_valid_ = true;
  std_msgs::Header header;
  header.stamp = stamp;
  header.frame_id = rgb_frame_id_;
  if (rgb_image_pub_.getNumSubscribers() > 0) {
    auto image = boost::make_shared<sensor_msgs::Image>();
    image->header = header;
    image->width = static_cast<uint32_t>(width);
    image->height = static_cast<uint32_t>(height);
    image->encoding = "rgb8";
    image->is_bigendian = false;
    image->step = static_cast<uint32_t>(width * 3);
    image->data = rgb_;
    rgb_image_pub_.publish(image);
  }
  if (rgb_info_pub_.getNumSubscribers() > 0) {
    PinholeIntrinsics intrinsics = device_->streamInfo(CameraStream::kColor).intrinsics;
    intrinsics.width = width;
    intrinsics.height = height;
    rgb_info_pub_.publish(cameraInfo(intrinsics, header));
  }
  publishCloud();
}

void OpenNI2DriverNodelet::publishCloud() {
  if (!depth_pending_ || points_pub_.getNumSubscribers() == 0) return;
  const bool with_color = device_->streamInfo(CameraStream::kColor).running;
  const bool registered = device_->depthRegisteredToColor();
  if (with_color) {
    // Pair with the colour frame of the same instant (within 60 % of a frame period).
    const int64_t dt = static_cast<int64_t>(depth_us_) - static_cast<int64_t>(rgb_us_);
    if (!rgb_valid_ || std::abs(dt) > frame_period_us_ * 6 / 10) return;
    if (!registered && !warned_unregistered_) {
      NODELET_WARN(
          "OpenNI2 camera: depth is not registered to colour; cloud colours are "
          "approximate");
      warned_unregistered_ = true;
    }
  }
  depth_pending_ = false;
  std_msgs::Header header;
  header.stamp = depth_stamp_;
  header.seq = ++clouds_published_;
  if (with_color) {
    const auto cloud = color_clouds_.next(depth_mm_.size());
    depthToCloud(depth_mm_.data(), depth_intrinsics_, rgb_.data(), rgb_width_, rgb_height_, *cloud);
    header.frame_id = registered ? rgb_frame_id_ : depth_frame_id_;
    cloud->header = pcl_conversions::toPCL(header);
    const boost::shared_ptr<const pcl::PointCloud<pcl::PointXYZRGB>> shared = cloud;
    bridge::markPublished(shared);  // lets Preprocess count it as received without a copy
    points_pub_.publish(shared);
  } else {
    const auto cloud = depth_clouds_.next(depth_mm_.size());
    depthToCloud(depth_mm_.data(), depth_intrinsics_, *cloud);
    header.frame_id = depth_frame_id_;
    cloud->header = pcl_conversions::toPCL(header);
    const boost::shared_ptr<const pcl::PointCloud<pcl::PointXYZ>> shared = cloud;
    bridge::markPublished(shared);
    points_pub_.publish(shared);
  }
}

// Wiring only: the session (core/camera_session.h) owns opening, back-off, loss and the
// streams; this loop hands it the wanted set and the config, sleeps as it asks and turns its
// frames into messages.
void OpenNI2DriverNodelet::run() {
  CameraSession session(
      *backend_, session_options_,
      [this](CameraLogLevel level, const std::string& message) { log(level, message); });
  bool config_restart = false;
  const auto applyConfig = [&] {
    OpenNI2Settings settings;
    settings.depth_mode = active_.depth_mode;
    settings.color_mode = active_.color_mode;
    settings.depth_registration = active_.depth_registration;
    settings.color_depth_synchronization = active_.color_depth_synchronization;
    settings.playback_repeat = playback_repeat_;
    backend_->setSettings(settings);
  };
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    active_ = config_;
    config_changed_ = false;
  }
  applyConfig();
  while (!shutting_down_) {
    {
      std::lock_guard<std::mutex> lock(config_mutex_);
      if (config_changed_) {
        config_restart = config_.depth_mode != active_.depth_mode ||
                         config_.color_mode != active_.color_mode ||
                         config_.depth_registration != active_.depth_registration ||
                         config_.color_depth_synchronization != active_.color_depth_synchronization;
        active_ = config_;
        config_changed_ = false;
        applyConfig();
      }
    }
    CameraFrame frame;
    const CameraSession::Step step =
        session.step(wantDepth(), wantColor(), config_restart, 100, &frame);
    config_restart = false;
    if (step.streams_started) {
      const CameraStreamInfo depth = session.device()->streamInfo(CameraStream::kDepth);
      if (depth.running) frame_period_us_ = 1000000 / depth.fps;
      clock_.reset();
      playback_.reset();
      depth_pending_ = rgb_valid_ = false;
    }
    switch (step.kind) {
      case CameraSession::Step::kFrame:
        device_ = session.device();
        if (frame.stream == CameraStream::kDepth) {
          handleDepth(frame);
        } else {
          handleColor(frame);
        }
        device_ = nullptr;
        break;
      case CameraSession::Step::kRetry:
      case CameraSession::Step::kIdle:
        sleepFor(step.wait_seconds);
        break;
      case CameraSession::Step::kNoFrame:
        break;
    }
  }
  session.close();
}

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::OpenNI2DriverNodelet, nodelet::Nodelet)
