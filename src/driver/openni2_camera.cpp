#include "tabletop_shapes/driver/openni2_camera.h"

#include "tabletop_shapes/core/oni_recording.h"

#include <OpenNI.h>
#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <optional>
#include <thread>

namespace tabletop_shapes {
namespace {

// OpenNI2 is process-global: initialise it once for every driver in the process and shut it
// down with the last one.
std::mutex& runtimeMutex() {
  static std::mutex instance;
  return instance;
}
int& runtimeUsers() {
  static int count = 0;
  return count;
}

// OpenNI2 2.2 can still cancel a recording's file player thread as the recording closes (even
// after letPlayerThreadStop) and unload that driver (libOniFile) in OpenNI::shutdown() while the
// thread is unwinding: the process then died in the unloaded code (1 child run in ~125 of
// test_openni2_camera, core dump: a cancelled thread in usleep, its caller unmapped). Marked
// RTLD_NODELETE once OpenNI2 has loaded it, the player's code stays mapped until the process
// ends; the handle is kept on purpose.
void keepFilePlayerMapped() {
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void*) {
        if (info->dlpi_name && std::strstr(info->dlpi_name, "/libOniFile.so")) {
          dlopen(info->dlpi_name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
        }
        return 0;
      },
      nullptr);
}

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

class OpenNI2Camera : public CameraDevice {
 public:
  explicit OpenNI2Camera(const OpenNI2Settings& settings) : settings_(settings) {}
  ~OpenNI2Camera() override {
    stopStreams();
    if (is_recording_ && !any_stream_created_) letPlayerThreadStop();
    device_.close();
  }

  openni::Status open(const std::string& uri) {
    const openni::Status status = device_.open(uri.c_str());
    if (status != openni::STATUS_OK) return status;
    is_recording_ = device_.isFile();
    if (is_recording_) {
      openni::PlaybackControl* playback = device_.getPlaybackControl();
      playback->setRepeatEnabled(settings_.playback_repeat);
      // Manual mode: the player hands out the next frame when the last one was read, in order
      // and without drops; the driver keeps the recorded schedule itself (PlaybackSchedule).
      playback->setSpeed(-1.0f);
    }
    return status;
  }

  bool isRecording() const override { return is_recording_; }

  std::string description() const override {
    const openni::DeviceInfo& info = device_.getDeviceInfo();
    return std::string(info.getVendor()) + " " + info.getName() + " (" + info.getUri() + ")";
  }

  void startStreams(bool depth, bool color, const CameraLog& log) override {
    if (depth && !depth_.created) createStream(depth_, openni::SENSOR_DEPTH, log);
    if (color && !color_.created) createStream(color_, openni::SENSOR_COLOR, log);
    applyDeviceSettings(log);
    for (Stream* stream : {&depth_, &color_}) {
      const bool wanted = stream == &depth_ ? depth : color;
      if (stream->created && wanted && !stream->running) {
        if (stream->video.start() == openni::STATUS_OK) {
          stream->running = true;
        } else {
          log(CameraLogLevel::kError,
              std::string("cannot start a stream: ") + openni::OpenNI::getExtendedError());
        }
      }
    }
  }

  void stopStreams() override {
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

  bool waitForFrame(int timeout_ms, CameraFrame* frame) override {
    openni::VideoStream* streams[2];
    int count = 0;
    if (depth_.running) streams[count++] = &depth_.video;
    if (color_.running) streams[count++] = &color_.video;
    int ready = -1;
    if (count == 0 ||
        openni::OpenNI::waitForAnyStream(streams, count, &ready, timeout_ms) != openni::STATUS_OK ||
        ready < 0 || streams[ready]->readFrame(&frame_) != openni::STATUS_OK || !frame_.isValid())
      return false;
    frame->stream = streams[ready] == &depth_.video ? CameraStream::kDepth : CameraStream::kColor;
    frame->device_us = frame_.getTimestamp();
    frame->width = frame_.getWidth();
    frame->height = frame_.getHeight();
    frame->data = frame_.getData();
    frame->bytes = static_cast<size_t>(std::max(0, frame_.getDataSize()));
    frame->depth_100um =
        frame_.getVideoMode().getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM;
    return true;
  }

  CameraStreamInfo streamInfo(CameraStream which) const override {
    const Stream& stream = which == CameraStream::kDepth ? depth_ : color_;
    CameraStreamInfo info;
    info.running = stream.running;
    info.intrinsics = stream.intrinsics;
    info.horizontal_fov = stream.horizontal_fov;
    info.vertical_fov = stream.vertical_fov;
    info.fps = stream.fps;
    return info;
  }

  bool depthRegisteredToColor() const override { return registered_ && color_.created; }

 private:
  struct Stream {
    openni::VideoStream video;
    bool created = false;
    bool running = false;
    PinholeIntrinsics intrinsics;
    double horizontal_fov = 0.0, vertical_fov = 0.0;
    int fps = 30;
  };

  // OpenNI2 2.2 cancels the player thread of a recording closed before any stream was created,
  // and the process then crashed at shutdown unwinding it (4 runs in 5: the driver unloaded
  // before anyone subscribed). A stream created and destroyed lets the thread end normally.
  void letPlayerThreadStop() {
    openni::VideoStream stream;
    for (openni::SensorType type : {openni::SENSOR_DEPTH, openni::SENSOR_COLOR}) {
      if (device_.hasSensor(type) && stream.create(device_, type) == openni::STATUS_OK) {
        stream.destroy();
        return;
      }
    }
  }

  void createStream(Stream& stream, openni::SensorType type, const CameraLog& log) {
    if (!device_.hasSensor(type)) return;
    if (stream.video.create(device_, type) != openni::STATUS_OK) {
      log(CameraLogLevel::kError,
          std::string("cannot create a stream: ") + openni::OpenNI::getExtendedError());
      return;
    }
    stream.created = true;
    any_stream_created_ = true;
    const bool depth = type == openni::SENSOR_DEPTH;
    const char* name = depth ? "depth" : "colour";
    const int mode = depth ? settings_.depth_mode : settings_.color_mode;
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
      const int width = size ? size->width : current.getResolutionX();
      const int height = size ? size->height : current.getResolutionY();
      const int fps = size ? size->fps : current.getFps();
      bool found = false;
      for (int i = 0; i < modes.getSize() && !found; ++i) {
        const openni::VideoMode& m = modes[i];
        if (m.getPixelFormat() == wanted_format && m.getResolutionX() == width &&
            m.getResolutionY() == height && m.getFps() == fps) {
          found = true;
          if (stream.video.setVideoMode(m) != openni::STATUS_OK) {
            log(CameraLogLevel::kWarning, "the device refused mode " + std::to_string(width) + "x" +
                                              std::to_string(height) + "@" + std::to_string(fps) +
                                              "; keeping its own");
          }
        }
      }
      if (!found) {
        log(CameraLogLevel::kWarning, std::string(name) + " mode " + std::to_string(mode) +
                                          " is not offered by the device; keeping its own");
      }
    }
    current = stream.video.getVideoMode();
    const bool format_ok = depth ? (current.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM ||
                                    current.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM)
                                 : current.getPixelFormat() == openni::PIXEL_FORMAT_RGB888;
    if (!format_ok) {
      log(CameraLogLevel::kWarning, std::string("unsupported ") + name + " pixel format " +
                                        std::to_string(current.getPixelFormat()) +
                                        "; stream not used");
      stream.video.destroy();
      stream.created = false;
      return;
    }
    stream.video.setMirroringEnabled(false);  // tolerated: file and dummy devices refuse
    bool default_fov = false;
    stream.horizontal_fov = stream.video.getHorizontalFieldOfView();
    stream.vertical_fov = stream.video.getVerticalFieldOfView();
    stream.intrinsics =
        intrinsicsFromFieldOfView(current.getResolutionX(), current.getResolutionY(),
                                  stream.horizontal_fov, stream.vertical_fov, &default_fov);
    if (default_fov) {
      log(CameraLogLevel::kWarning,
          std::string("the ") + name + " stream reports no field of view; using the Kinect's");
    }
    stream.fps = std::max(1, current.getFps());
    char fx[32];
    std::snprintf(fx, sizeof(fx), "%g", stream.intrinsics.fx);
    log(CameraLogLevel::kInfo, std::string(name) + " " + std::to_string(current.getResolutionX()) +
                                   "x" + std::to_string(current.getResolutionY()) + "@" +
                                   std::to_string(current.getFps()) + " Hz, fx " + fx);
  }

  void applyDeviceSettings(const CameraLog& log) {
    // Hardware registration and frame sync exist on PS1080 devices; others refuse: tolerated.
    registered_ = is_recording_;  // a recording holds whatever was recorded: take it as registered
    if (!is_recording_ && depth_.created && color_.created) {
      const auto mode = settings_.depth_registration ? openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR
                                                     : openni::IMAGE_REGISTRATION_OFF;
      if (device_.isImageRegistrationModeSupported(mode) &&
          device_.setImageRegistrationMode(mode) == openni::STATUS_OK) {
        registered_ = settings_.depth_registration;
      } else if (settings_.depth_registration) {
        log(CameraLogLevel::kWarning, "this device cannot register depth to colour");
      }
      device_.setDepthColorSyncEnabled(settings_.color_depth_synchronization);
    }
  }

  const OpenNI2Settings& settings_;
  openni::Device device_;
  bool is_recording_ = false;
  bool any_stream_created_ = false;
  bool registered_ = false;
  Stream depth_, color_;
  openni::VideoFrameRef frame_;  // the last frame read: CameraFrame::data points into it
};

// The URI of the device that device_id names ("" the first, "#N" the N-th, a URI as given,
// also "Dummy", which is not enumerated, else a serial number); empty and *problem if none.
std::string deviceUri(const std::string& device_id, std::string* problem) {
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  if (device_id.empty()) {
    if (devices.getSize() == 0) {
      *problem =
          "no OpenNI2 device is connected (Xtion / PrimeSense via PS1080; a Kinect v1 "
          "needs the FreenectDriver plugin, see launch/camera.launch)";
      return "";
    }
    return devices[0].getUri();
  }
  if (device_id[0] == '#') {
    const int index = std::atoi(device_id.c_str() + 1);
    if (index < 1 || index > devices.getSize()) {
      *problem = "device_id '" + device_id + "': " + std::to_string(devices.getSize()) +
                 " OpenNI2 device(s) connected";
      return "";
    }
    return devices[index - 1].getUri();
  }
  for (int i = 0; i < devices.getSize(); ++i) {
    if (device_id == devices[i].getUri()) return device_id;
  }
  for (int i = 0; i < devices.getSize(); ++i) {
    openni::Device candidate;
    if (candidate.open(devices[i].getUri()) != openni::STATUS_OK) continue;
    char serial[128] = {};
    int size = sizeof(serial);
    const bool match = candidate.getProperty(ONI_DEVICE_PROPERTY_SERIAL_NUMBER, serial, &size) ==
                           openni::STATUS_OK &&
                       device_id == serial;
    candidate.close();
    if (match) return devices[i].getUri();
  }
  return device_id;
}

}  // namespace

OpenNI2Backend::OpenNI2Backend(std::string* error) {
  std::lock_guard<std::mutex> lock(runtimeMutex());
  if (runtimeUsers() == 0 && openni::OpenNI::initialize() != openni::STATUS_OK) {
    *error = std::string("OpenNI2 initialisation failed: ") + openni::OpenNI::getExtendedError();
    return;
  }
  if (runtimeUsers() == 0) keepFilePlayerMapped();
  ++runtimeUsers();
  initialized_ = true;
}

OpenNI2Backend::~OpenNI2Backend() {
  if (!initialized_) return;
  std::lock_guard<std::mutex> lock(runtimeMutex());
  if (--runtimeUsers() == 0) openni::OpenNI::shutdown();
}

std::unique_ptr<CameraDevice> OpenNI2Backend::open(const std::string& device_id,
                                                   std::string* problem) {
  if (!initialized_) {
    *problem = "OpenNI2 is not initialised";
    return nullptr;
  }
  // A recording's path is its URI (the session checked the file).
  const std::string uri = looksLikeRecording(device_id) ? device_id : deviceUri(device_id, problem);
  if (uri.empty()) return nullptr;
  auto camera = std::make_unique<OpenNI2Camera>(settings_);
  if (camera->open(uri) != openni::STATUS_OK) {
    const std::string detail = openni::OpenNI::getExtendedError();
    *problem = "cannot open device '" + device_id + "'" +
               (uri != device_id ? " (" + uri + ")" : "") + (detail.empty() ? "" : ": " + detail);
    return nullptr;
  }
  return camera;
}

}  // namespace tabletop_shapes
