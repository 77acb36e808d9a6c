// OpenNI2 devices (PrimeSense / Asus Xtion through PS1080, a Kinect v1 through the
// FreenectDriver plugin, .oni recordings through libOniFile) behind the CameraSession interface
// (core/camera_session.h). ROS-free; the header keeps OpenNI.h out of its users.
#pragma once

#include "tabletop_shapes/core/camera_session.h"

#include <string>

namespace tabletop_shapes {

// The device settings of the driver's dynamic_reconfigure config that OpenNI2 applies.
struct OpenNI2Settings {
  int depth_mode = 0, color_mode = 0;  // openni2_camera's mode numbers; 0: the device's own
  bool depth_registration = true;
  bool color_depth_synchronization = false;
  bool playback_repeat = true;  // recordings: loop
};

class OpenNI2Backend : public CameraBackend {
 public:
  // OpenNI2 is process-global: initialised with the first backend (false and *error when that
  // fails; then open() refuses), shut down with the last.
  explicit OpenNI2Backend(std::string* error);
  ~OpenNI2Backend() override;
  OpenNI2Backend(const OpenNI2Backend&) = delete;
  OpenNI2Backend& operator=(const OpenNI2Backend&) = delete;
  bool initialized() const { return initialized_; }

  // Used by the devices it opens from their next stream start on (the caller's thread only).
  void setSettings(const OpenNI2Settings& settings) { settings_ = settings; }

  std::unique_ptr<CameraDevice> open(const std::string& device_id, std::string* problem) override;

 private:
  bool initialized_ = false;
  OpenNI2Settings settings_;
};

}  // namespace tabletop_shapes
