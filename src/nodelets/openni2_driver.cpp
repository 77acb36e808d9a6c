// tabletop_shapes/OpenNI2Driver: an OpenNI2 camera (PrimeSense / Asus Xtion through OpenNI2's
// PS1080 driver, a Kinect v1 through the FreenectDriver plugin, .oni recordings through
// libOniFile) as a nodelet with openni2_camera's topic names:
//   depth/image_raw + depth/camera_info       16UC1, millimetres
//   rgb/image_raw + rgb/camera_info           rgb8
//   depth_registered/points                   organised XYZRGB (XYZ when there is no colour),
//                                             published as a shared pointer: Preprocess in the
//                                             same manager gets an XYZRGB cloud without a copy
//                                             (an XYZ one is copied once)
// One worker thread owns every OpenNI2 object: it opens the device (retrying with back-off and a
// throttled message while it is missing), runs the streams only while someone subscribes,
// pairs depth and colour frames by timestamp, paces recordings at their recorded rate and
// closes everything cleanly (OpenNI2 needs time between VideoStream::stop() and destroy()).
#include "tabletop_shapes/core/depth_to_cloud.h"
#include "tabletop_shapes/core/oni_recording.h"
#include "tabletop_shapes/core/playback_schedule.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/OpenNI2DriverConfig.h"

#include <OpenNI.h>
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

// OpenNI2 is process-global: initialise it once for every driver nodelet in the manager and
// shut it down with the last one.
class OpenNIRuntime {
 public:
  static bool acquire(std::string* error) {
    std::lock_guard<std::mutex> lock(mutex());
    if (users() == 0 && openni::OpenNI::initialize() != openni::STATUS_OK) {
      *error = std::string("OpenNI2 initialisation failed: ") + openni::OpenNI::getExtendedError();
      return false;
    }
    ++users();
    return true;
  }
  static void release() {
    std::lock_guard<std::mutex> lock(mutex());
    if (--users() == 0) openni::OpenNI::shutdown();
  }

 private:
  static std::mutex& mutex() {
    static std::mutex instance;
    return instance;
  }
  static int& users() {
    static int count = 0;
    return count;
  }
};

// openni2_camera's mode numbers (see cfg/OpenNI2Driver.cfg); 0 = keep the device's mode.
struct ModeSize {
  int width, height, fps;
};
std::optional<ModeSize> modeSize(int mode) {
  static const ModeSize kModes[] = {
      {1280, 1024, 30}, {1280, 1024, 15}, {1280, 720, 30}, {1280, 720, 15}, {640, 480, 30},
      {640, 480, 25},   {320, 240, 25},   {320, 240, 30},  {320, 240, 60},  {160, 120, 25},
      {160, 120, 30},   {160, 120, 60},   {640, 400, 30},  {320, 200, 30},  {1280, 800, 30},
      {640, 400, 60},   {320, 200, 60}};
  if (mode < 1 || mode > static_cast<int>(sizeof(kModes) / sizeof(kModes[0]))) return {};
  return kModes[mode - 1];
}

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
  // One camera stream and its frame bookkeeping.
  struct Stream {
    openni::VideoStream video;
    bool created = false;
    bool running = false;
    PinholeIntrinsics intrinsics;
    uint64_t frames_seen = 0;
  };

  void onInit() override;
  void reconfigure(Config& config, uint32_t level);
  void run();
  bool sleepUntil(Clock::time_point end);  // false when shutting down
  bool sleepFor(double seconds);
  bool openDevice(std::string* problem);
  void closeDevice();
  bool createStream(Stream& stream, openni::SensorType type, int mode, std::string* problem);
  void startStreams(bool depth, bool color);
  void stopStreams();
  void applyDeviceSettings();
  bool wantDepth() const;
  bool wantColor() const;
  void handleDepth(const openni::VideoFrameRef& frame);
  void handleColor(const openni::VideoFrameRef& frame);
  void publishCloud();
  ros::Time paceRecording(int stream, uint64_t device_us);  // stream: 0 depth, 1 colour
  void reportProblem(const std::string& problem, const std::string& detail = "");

  // parameters
  std::string device_id_;
  std::string depth_frame_id_, rgb_frame_id_;
  double frame_timeout_ = 3.0;
  double reconnect_max_interval_ = 10.0;
  double problem_report_interval_ = 10.0;
  bool playback_repeat_ = true;
  std::mutex config_mutex_;
  Config config_;
  bool config_changed_ = false;
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  Config active_;  // the worker's copy

  ros::Publisher depth_image_pub_, depth_info_pub_, rgb_image_pub_, rgb_info_pub_, points_pub_;
  std::thread worker_;
  std::atomic<bool> shutting_down_{false};
  bool openni_acquired_ = false;

  // device state (worker thread only)
  openni::Device device_;
  bool device_open_ = false;
  bool is_recording_ = false;
  bool registered_ = false;
  Stream depth_, color_;
  FrameClock clock_;
  std::string last_problem_;
  Clock::time_point last_problem_time_;
  // pairing: the last published-worthy frames and their device times
  std::vector<uint16_t> depth_mm_;
  uint64_t depth_us_ = 0;
  ros::Time depth_stamp_;
  bool depth_pending_ = false;
  uint32_t clouds_published_ = 0;  // header.seq: Preprocess counts the clouds it drops
  std::vector<uint8_t> rgb_;
  int rgb_width_ = 0, rgb_height_ = 0;
  uint64_t rgb_us_ = 0;
  bool rgb_valid_ = false;
  bool warned_unregistered_ = false;
  bool started_depth_ = false, started_color_ = false;  // the wanted set the streams run for
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
  if (openni_acquired_) OpenNIRuntime::release();
}

void OpenNI2DriverNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  pnh.param<std::string>("device_id", device_id_, "");
  pnh.param<std::string>("depth_frame_id", depth_frame_id_, "camera_depth_optical_frame");
  pnh.param<std::string>("rgb_frame_id", rgb_frame_id_, "camera_rgb_optical_frame");
  pnh.param("frame_timeout", frame_timeout_, 3.0);
  pnh.param("reconnect_max_interval", reconnect_max_interval_, 10.0);
  pnh.param("problem_report_interval", problem_report_interval_, 10.0);
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
  openni_acquired_ = OpenNIRuntime::acquire(&error);
  if (!openni_acquired_) {
    NODELET_ERROR_STREAM(error << "; the camera driver stays idle");
    return;
  }
  NODELET_INFO_STREAM("OpenNI2 driver: device_id '"
                      << device_id_ << "' ("
                      << (device_id_.empty() ? "the first device" : "as given")
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

void OpenNI2DriverNodelet::reportProblem(const std::string& problem, const std::string& detail) {
  // Throttled: a new problem at once, the same one again every problem_report_interval.
  const auto now = Clock::now();
  if (problem != last_problem_ ||
      now - last_problem_time_ > std::chrono::duration<double>(problem_report_interval_)) {
    NODELET_ERROR_STREAM("OpenNI2 camera: " << problem << detail);
    last_problem_ = problem;
    last_problem_time_ = now;
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

bool OpenNI2DriverNodelet::openDevice(std::string* problem) {
  std::string uri = device_id_;
  if (looksLikeRecording(device_id_)) {
    *problem = oniRecordingProblem(device_id_);
    if (!problem->empty()) return false;
  } else {
    openni::Array<openni::DeviceInfo> devices;
    openni::OpenNI::enumerateDevices(&devices);
    if (device_id_.empty()) {
      if (devices.getSize() == 0) {
        *problem =
            "no OpenNI2 device is connected (Xtion / PrimeSense via PS1080; a Kinect v1 "
            "needs the FreenectDriver plugin, see launch/camera.launch)";
        return false;
      }
      uri = devices[0].getUri();
    } else if (device_id_[0] == '#') {
      const int index = std::atoi(device_id_.c_str() + 1);
      if (index < 1 || index > devices.getSize()) {
        *problem = "device_id '" + device_id_ + "': " + std::to_string(devices.getSize()) +
                   " OpenNI2 device(s) connected";
        return false;
      }
      uri = devices[index - 1].getUri();
    } else {
      // A URI as given (also "Dummy", which is not enumerated), else a serial number.
      bool found = false;
      for (int i = 0; i < devices.getSize() && !found; ++i) {
        if (device_id_ == devices[i].getUri()) found = true;
      }
      for (int i = 0; i < devices.getSize() && !found; ++i) {
        openni::Device candidate;
        if (candidate.open(devices[i].getUri()) != openni::STATUS_OK) continue;
        char serial[128] = {};
        int size = sizeof(serial);
        if (candidate.getProperty(ONI_DEVICE_PROPERTY_SERIAL_NUMBER, serial, &size) ==
                openni::STATUS_OK &&
            device_id_ == serial) {
          uri = devices[i].getUri();
          found = true;
        }
        candidate.close();
      }
    }
  }
  if (device_.open(uri.c_str()) != openni::STATUS_OK) {
    const std::string detail = openni::OpenNI::getExtendedError();
    *problem = "cannot open device '" + device_id_ + "'" +
               (uri != device_id_ ? " (" + uri + ")" : "") + (detail.empty() ? "" : ": " + detail);
    return false;
  }
  device_open_ = true;
  is_recording_ = device_.isFile();
  if (is_recording_) {
    openni::PlaybackControl* playback = device_.getPlaybackControl();
    playback->setRepeatEnabled(playback_repeat_);
    // Manual mode: the player hands out the next frame when the last one was read, in order
    // and without drops; the driver keeps the recorded schedule itself (paceRecording).
    playback->setSpeed(-1.0f);
  }
  const openni::DeviceInfo& info = device_.getDeviceInfo();
  NODELET_INFO_STREAM("OpenNI2 camera: opened " << info.getVendor() << " " << info.getName() << " ("
                                                << info.getUri() << ")");
  if (!last_problem_.empty()) NODELET_INFO("OpenNI2 camera: the device is back");
  last_problem_.clear();
  return true;
}

bool OpenNI2DriverNodelet::createStream(Stream& stream, openni::SensorType type, int mode,
                                        std::string* problem) {
  if (!device_.hasSensor(type)) return false;
  if (stream.video.create(device_, type) != openni::STATUS_OK) {
    *problem = std::string("cannot create a stream: ") + openni::OpenNI::getExtendedError();
    return false;
  }
  stream.created = true;
  const bool depth = type == openni::SENSOR_DEPTH;
  const openni::PixelFormat wanted_format =
      depth ? openni::PIXEL_FORMAT_DEPTH_1_MM : openni::PIXEL_FORMAT_RGB888;
  openni::VideoMode current = stream.video.getVideoMode();
  const std::optional<ModeSize> size = modeSize(mode);
  const bool change =
      current.getPixelFormat() != wanted_format ||
      (size && (current.getResolutionX() != size->width ||
                current.getResolutionY() != size->height || current.getFps() != size->fps));
  if (change && !is_recording_) {  // recordings have their one mode
    const openni::Array<openni::VideoMode>& modes =
        stream.video.getSensorInfo().getSupportedVideoModes();
    bool found = false;
    for (int i = 0; i < modes.getSize() && !found; ++i) {
      const openni::VideoMode& m = modes[i];
      const int width = size ? size->width : current.getResolutionX();
      const int height = size ? size->height : current.getResolutionY();
      const int fps = size ? size->fps : current.getFps();
      if (m.getPixelFormat() == wanted_format && m.getResolutionX() == width &&
          m.getResolutionY() == height && m.getFps() == fps) {
        found = true;
        if (stream.video.setVideoMode(m) != openni::STATUS_OK) {
          NODELET_WARN_STREAM("OpenNI2 camera: the device refused mode "
                              << width << "x" << height << "@" << fps << "; keeping its own");
        }
      }
    }
    if (!found) {
      NODELET_WARN_STREAM("OpenNI2 camera: " << (depth ? "depth" : "colour") << " mode " << mode
                                             << " is not offered by the device; keeping its own");
    }
  }
  current = stream.video.getVideoMode();
  const bool format_ok = depth ? (current.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM ||
                                  current.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM)
                               : current.getPixelFormat() == openni::PIXEL_FORMAT_RGB888;
  if (!format_ok) {
    NODELET_WARN_STREAM("OpenNI2 camera: unsupported "
                        << (depth ? "depth" : "colour") << " pixel format "
                        << current.getPixelFormat() << "; stream not used");
    stream.video.destroy();
    stream.created = false;
    return false;
  }
  stream.video.setMirroringEnabled(false);  // tolerated: file and dummy devices refuse
  bool default_fov = false;
  stream.intrinsics = intrinsicsFromFieldOfView(
      current.getResolutionX(), current.getResolutionY(), stream.video.getHorizontalFieldOfView(),
      stream.video.getVerticalFieldOfView(), &default_fov);
  if (default_fov) {
    NODELET_WARN_STREAM("OpenNI2 camera: the "
                        << (depth ? "depth" : "colour")
                        << " stream reports no field of view; using the Kinect's");
  }
  if (depth) frame_period_us_ = 1000000 / std::max(1, current.getFps());
  NODELET_INFO_STREAM("OpenNI2 camera: " << (depth ? "depth " : "colour ")
                                         << current.getResolutionX() << "x"
                                         << current.getResolutionY() << "@" << current.getFps()
                                         << " Hz, fx " << stream.intrinsics.fx);
  return true;
}

void OpenNI2DriverNodelet::applyDeviceSettings() {
  // Hardware registration and frame sync exist on PS1080 devices; others refuse: tolerated.
  registered_ = is_recording_;  // a recording holds whatever was recorded: take it as registered
  if (!is_recording_ && depth_.created && color_.created) {
    const auto mode = active_.depth_registration ? openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR
                                                 : openni::IMAGE_REGISTRATION_OFF;
    if (device_.isImageRegistrationModeSupported(mode) &&
        device_.setImageRegistrationMode(mode) == openni::STATUS_OK) {
      registered_ = active_.depth_registration;
    } else if (active_.depth_registration) {
      NODELET_WARN("OpenNI2 camera: this device cannot register depth to colour");
    }
    device_.setDepthColorSyncEnabled(active_.color_depth_synchronization);
  }
}

void OpenNI2DriverNodelet::startStreams(bool depth, bool color) {
  std::string problem;
  if (depth && !depth_.created)
    createStream(depth_, openni::SENSOR_DEPTH, active_.depth_mode, &problem);
  if (color && !color_.created)
    createStream(color_, openni::SENSOR_COLOR, active_.color_mode, &problem);
  if (!problem.empty()) reportProblem(problem);
  applyDeviceSettings();
  for (Stream* stream : {&depth_, &color_}) {
    const bool wanted = stream == &depth_ ? depth : color;
    if (stream->created && wanted && !stream->running) {
      if (stream->video.start() == openni::STATUS_OK) {
        stream->running = true;
      } else {
        reportProblem(std::string("cannot start a stream: ") + openni::OpenNI::getExtendedError());
      }
    }
  }
  clock_.reset();
  playback_.reset();
  depth_pending_ = rgb_valid_ = false;
}

void OpenNI2DriverNodelet::stopStreams() {
  bool stopped = false;
  for (Stream* stream : {&depth_, &color_}) {
    if (stream->running) {
      stream->video.stop();
      stream->running = false;
      stopped = true;
    }
  }
  // OpenNI2 crashes when a stream is destroyed right after stop() (measured with the Dummy
  // device): give its threads time to let go.
  if (stopped) std::this_thread::sleep_for(std::chrono::milliseconds(150));
  for (Stream* stream : {&depth_, &color_}) {
    if (stream->created) {
      stream->video.destroy();
      stream->created = false;
    }
  }
}

void OpenNI2DriverNodelet::closeDevice() {
  stopStreams();
  started_depth_ = started_color_ = false;
  if (device_open_) {
    device_.close();
    device_open_ = false;
  }
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

void OpenNI2DriverNodelet::handleDepth(const openni::VideoFrameRef& frame) {
  const uint64_t device_us = frame.getTimestamp();
  const ros::Time stamp =
      is_recording_ ? paceRecording(0, device_us) : clock_.stamp(device_us, true);
  if (depth_.frames_seen++ % static_cast<uint64_t>(active_.data_skip + 1) != 0) return;
  const int width = frame.getWidth(), height = frame.getHeight();
  const int pixels = width * height;
  const auto* data = static_cast<const uint16_t*>(frame.getData());
  if (frame.getDataSize() < pixels * 2) return;
  depth_mm_.assign(data, data + pixels);
  if (frame.getVideoMode().getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM) {
    for (uint16_t& z : depth_mm_) z = static_cast<uint16_t>((z + 5) / 10);
  }
  correctDepth(depth_mm_.data(), pixels, DepthCorrection{active_.z_offset_mm, active_.z_scaling});
  depth_us_ = device_us;
  depth_stamp_ = stamp;

  // The depth image is in the colour camera's frame once registered.
  PinholeIntrinsics intrinsics = depth_.intrinsics;
  intrinsics.width = width;
  intrinsics.height = height;
  std_msgs::Header header;
  header.stamp = depth_stamp_;
  header.frame_id = registered_ && color_.created ? rgb_frame_id_ : depth_frame_id_;
  if (registered_ && color_.created) {
    intrinsics = intrinsicsFromFieldOfView(width, height, color_.video.getHorizontalFieldOfView(),
                                           color_.video.getVerticalFieldOfView());
  } else {
    intrinsics.cx -= active_.depth_ir_offset_x;
    intrinsics.cy -= active_.depth_ir_offset_y;
  }
  depth_.intrinsics = intrinsics;
  if (depth_image_pub_.getNumSubscribers() > 0) {
    auto image = boost::make_shared<sensor_msgs::Image>();
    image->header = header;
    image->width = static_cast<uint32_t>(width);
    image->height = static_cast<uint32_t>(height);
    image->encoding = "16UC1";
    image->is_bigendian = false;
    image->step = static_cast<uint32_t>(width * 2);
    image->data.resize(static_cast<size_t>(pixels) * 2);
    std::memcpy(image->data.data(), depth_mm_.data(), image->data.size());
    depth_image_pub_.publish(image);
  }
  if (depth_info_pub_.getNumSubscribers() > 0)
    depth_info_pub_.publish(cameraInfo(intrinsics, header));
  depth_pending_ = true;
  publishCloud();
}

void OpenNI2DriverNodelet::handleColor(const openni::VideoFrameRef& frame) {
  const uint64_t device_us = frame.getTimestamp();
  const ros::Time stamp =
      is_recording_ ? paceRecording(1, device_us) : clock_.stamp(device_us, true);
  if (color_.frames_seen++ % static_cast<uint64_t>(active_.data_skip + 1) != 0) return;
  const int width = frame.getWidth(), height = frame.getHeight();
  const size_t bytes = static_cast<size_t>(width) * height * 3;
  if (frame.getDataSize() < static_cast<int>(bytes)) return;
  const auto* data = static_cast<const uint8_t*>(frame.getData());
  rgb_.assign(data, data + bytes);
  rgb_width_ = width;
  rgb_height_ = height;
  rgb_us_ = device_us;
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
    PinholeIntrinsics intrinsics = color_.intrinsics;
    intrinsics.width = width;
    intrinsics.height = height;
    rgb_info_pub_.publish(cameraInfo(intrinsics, header));
  }
  publishCloud();
}

void OpenNI2DriverNodelet::publishCloud() {
  if (!depth_pending_ || points_pub_.getNumSubscribers() == 0) return;
  const bool with_color = color_.running;
  if (with_color) {
    // Pair with the colour frame of the same instant (within 60 % of a frame period).
    const int64_t dt = static_cast<int64_t>(depth_us_) - static_cast<int64_t>(rgb_us_);
    if (!rgb_valid_ || std::abs(dt) > frame_period_us_ * 6 / 10) return;
    if (!registered_ && !warned_unregistered_) {
      NODELET_WARN(
          "OpenNI2 camera: depth is not registered to colour; cloud colours are "
          "approximate");
      warned_unregistered_ = true;
    }
  }
  depth_pending_ = false;
  const PinholeIntrinsics& intrinsics = depth_.intrinsics;
  std_msgs::Header header;
  header.stamp = depth_stamp_;
  header.seq = ++clouds_published_;
  if (with_color) {
    auto cloud = boost::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>();
    depthToCloud(depth_mm_.data(), intrinsics, rgb_.data(), rgb_width_, rgb_height_, *cloud);
    header.frame_id = registered_ ? rgb_frame_id_ : depth_frame_id_;
    cloud->header = pcl_conversions::toPCL(header);
    const boost::shared_ptr<const pcl::PointCloud<pcl::PointXYZRGB>> shared = cloud;
    bridge::markPublished(shared);  // lets Preprocess count it as received without a copy
    points_pub_.publish(shared);
  } else {
    auto cloud = boost::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    depthToCloud(depth_mm_.data(), intrinsics, *cloud);
    header.frame_id = depth_frame_id_;
    cloud->header = pcl_conversions::toPCL(header);
    const boost::shared_ptr<const pcl::PointCloud<pcl::PointXYZ>> shared = cloud;
    bridge::markPublished(shared);
    points_pub_.publish(shared);
  }
}

void OpenNI2DriverNodelet::run() {
  double backoff = 0.5;
  bool config_restart = false;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    active_ = config_;
    config_changed_ = false;
  }
  Clock::time_point last_frame = Clock::now();
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
      }
    }
    if (!device_open_) {
      std::string problem;
      if (!openDevice(&problem)) {
        char retry[64];
        std::snprintf(retry, sizeof(retry), "; retrying in %.1f s", backoff);
        reportProblem(problem, retry);
        if (!sleepFor(backoff)) break;
        backoff = std::min(backoff * 2.0, reconnect_max_interval_);
        continue;
      }
      backoff = 0.5;
    }
    // Restart the streams when the wanted set changes (or a mode did), not when a sensor the
    // device lacks is wanted: a device without colour gives XYZ clouds.
    const bool depth = wantDepth(), color = wantColor();
    if (config_restart || depth != started_depth_ || color != started_color_) {
      const bool was_idle = !started_depth_ && !started_color_;
      stopStreams();
      config_restart = false;
      started_depth_ = depth;
      started_color_ = color;
      if (depth || color) {
        startStreams(depth, color);
        last_frame = Clock::now();
        if (was_idle) NODELET_INFO("OpenNI2 camera: streaming (someone subscribed)");
      } else {
        NODELET_INFO("OpenNI2 camera: no subscribers; streams stopped");
      }
    }
    std::vector<openni::VideoStream*> streams;
    if (depth_.running) streams.push_back(&depth_.video);
    if (color_.running) streams.push_back(&color_.video);
    if (streams.empty()) {
      sleepFor(0.1);
      continue;
    }
    int ready = -1;
    const openni::Status status = openni::OpenNI::waitForAnyStream(
        streams.data(), static_cast<int>(streams.size()), &ready, 100);
    if (status == openni::STATUS_OK && ready >= 0) {
      openni::VideoFrameRef frame;
      if (streams[ready]->readFrame(&frame) == openni::STATUS_OK && frame.isValid()) {
        last_frame = Clock::now();
        if (streams[ready] == &depth_.video) {
          handleDepth(frame);
        } else {
          handleColor(frame);
        }
      }
      continue;
    }
    const double silent = std::chrono::duration<double>(Clock::now() - last_frame).count();
    if (silent > frame_timeout_) {
      char seconds[32];
      std::snprintf(seconds, sizeof(seconds), "%.1f", silent);
      reportProblem("no frames from '" + device_id_ + "' for " + seconds +
                    " s: the camera was unplugged or stalled; reopening it");
      closeDevice();
    }
  }
  closeDevice();
}

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::OpenNI2DriverNodelet, nodelet::Nodelet)
