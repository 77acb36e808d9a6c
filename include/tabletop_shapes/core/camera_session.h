// The camera driver's device handling, free of ROS and of OpenNI2 so that it is unit-tested
// with a fake device (test/core/test_camera_session.cpp): opening the device (a recording is
// checked first: missing, truncated, damaged or not an .oni), retrying with back-off while it
// is missing, throttled problem messages, running the streams only while someone wants them,
// and closing and reopening a device that stopped delivering frames (unplugged, stalled, a
// recording deleted or replaced under the player). The OpenNI2 nodelet implements the device
// (src/driver/openni2_camera.cpp) and turns the frames into messages.
#pragma once

#include "tabletop_shapes/core/depth_to_cloud.h"

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace tabletop_shapes {

enum class CameraStream { kDepth, kColor };

// One frame as the device delivered it; data stays valid until the next CameraSession::step.
struct CameraFrame {
  CameraStream stream = CameraStream::kDepth;
  uint64_t device_us = 0;  // the device's own clock
  int width = 0, height = 0;
  const void* data = nullptr;
  size_t bytes = 0;
  bool depth_100um = false;  // depth in 0.1 mm steps instead of 1 mm
};

// A running stream of an open device.
struct CameraStreamInfo {
  bool running = false;
  PinholeIntrinsics intrinsics;
  double horizontal_fov = 0.0, vertical_fov = 0.0;  // [rad]
  int fps = 30;
};

// What the session and the device report, for the driver's log.
enum class CameraLogLevel { kInfo, kWarning, kError };
using CameraLog = std::function<void(CameraLogLevel level, const std::string& message)>;

// One opened device (a camera or a recording).
class CameraDevice {
 public:
  virtual ~CameraDevice() = default;
  virtual bool isRecording() const = 0;
  // "vendor name (uri)", for the log.
  virtual std::string description() const = 0;
  // Starts the wanted streams the device has (a device without colour gives depth only);
  // anything refused goes to `log`.
  virtual void startStreams(bool depth, bool color, const CameraLog& log) = 0;
  virtual void stopStreams() = 0;
  // Waits up to timeout_ms for the next frame of a running stream; false when none came.
  virtual bool waitForFrame(int timeout_ms, CameraFrame* frame) = 0;
  virtual CameraStreamInfo streamInfo(CameraStream stream) const = 0;
  // True when depth frames are registered to the colour camera (hardware registration on, or
  // a recording, which holds whatever was recorded).
  virtual bool depthRegisteredToColor() const = 0;
};

// Opens devices by the driver's device_id ("" the first device, "#N" the N-th, a URI or serial
// number, or a recording's path).
class CameraBackend {
 public:
  virtual ~CameraBackend() = default;
  // nullptr and *problem (one line naming the cause) when the device cannot be opened.
  virtual std::unique_ptr<CameraDevice> open(const std::string& device_id,
                                             std::string* problem) = 0;
};

struct CameraSessionOptions {
  std::string device_id;
  double frame_timeout = 3.0;             // [s] without frames: the device is lost, reopen it
  double reconnect_max_interval = 10.0;   // [s] the back-off between open attempts grows to this
  double problem_report_interval = 10.0;  // [s] the same problem is logged again after this
};

class CameraSession {
 public:
  using Clock = std::chrono::steady_clock;
  using Now = std::function<Clock::time_point()>;

  struct Step {
    enum Kind {
      kFrame,    // *frame holds a frame
      kNoFrame,  // waited, nothing came (the device may be closed now: lost)
      kRetry,    // the device could not be opened: sleep wait_seconds, then step again
      kIdle,     // nobody wants a stream: sleep wait_seconds
    } kind = kNoFrame;
    double wait_seconds = 0.0;
    bool streams_started = false;  // the streams were (re)started: frame pairing starts afresh
  };

  // `now` is the clock the timeouts are measured on (a fake one in tests).
  CameraSession(CameraBackend& backend, CameraSessionOptions options, CameraLog log,
                Now now = Clock::now);
  ~CameraSession() { close(); }
  CameraSession(const CameraSession&) = delete;
  CameraSession& operator=(const CameraSession&) = delete;

  // One turn of the driver's loop: opens the device when it is closed, (re)starts the streams
  // when the wanted set changed or `restart` (a mode changed), waits up to wait_ms for a frame
  // and closes the device after frame_timeout seconds without one.
  Step step(bool want_depth, bool want_color, bool restart, int wait_ms, CameraFrame* frame);

  // Stops the streams and closes the device (also on destruction).
  void close();

  bool isOpen() const { return device_ != nullptr; }
  // The open device (nullptr when closed).
  const CameraDevice* device() const { return device_.get(); }
  const CameraSessionOptions& options() const { return options_; }

 private:
  bool open();
  void report(const std::string& problem, const std::string& detail = "");

  CameraBackend& backend_;
  CameraSessionOptions options_;
  CameraLog log_;
  Now now_;
  std::unique_ptr<CameraDevice> device_;
  double backoff_ = 0.5;
  bool started_depth_ = false, started_color_ = false;  // the wanted set the streams run for
  Clock::time_point last_frame_;
  std::string last_problem_;
  Clock::time_point last_problem_time_;
};

}  // namespace tabletop_shapes
