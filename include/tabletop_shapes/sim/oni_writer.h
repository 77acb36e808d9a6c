// Writes OpenNI2 recordings (.oni, format v1.0.1.0, uncompressed) without OpenNI2: a depth
// stream (uint16 millimetres, 0 = no reading) and optionally an RGB888 colour stream of the same
// resolution, as libOniFile (OpenNI2's file-device driver) reads them. Used to turn rendered
// table scenes into recordings the OpenNI2 driver nodelet can play.
//
// Layout written (all little-endian, records as in OpenNI2's Source/Core/OniDataRecords.cpp):
// file header; per stream NODE_ADDED + properties (frame size, video mode, pixel format, field
// of view, cropping, mirror); NODE_STATE_READY + NODE_DATA_BEGIN; the frames as NEW_DATA
// (depth and colour of one instant share a timestamp); NODE_REMOVED and SEEK_TABLE per stream;
// END. NODE_ADDED records and the file header are patched on close() with the frame counts, the
// last timestamp and the seek-table positions.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

namespace tabletop_shapes {
namespace sim {

// One RGB-D instant: depth in millimetres (0 = no return) and RGB888, row-major, same size.
struct RgbdFrame {
  int width = 0;
  int height = 0;
  std::vector<uint16_t> depth_mm;  // width * height
  std::vector<uint8_t> rgb;        // width * height * 3, or empty for depth-only recordings
};

// Depth (z in mm, rounded; 0 where z is NaN or outside 1 .. 65535 mm) and colour of an
// organised cloud in the optical frame, e.g. a rendered scene.
RgbdFrame rgbdFrameFromCloud(const pcl::PointCloud<pcl::PointXYZRGB>& cloud);

struct OniRecordingOptions {
  int width = 640;
  int height = 480;
  int fps = 30;
  // Fields of view [rad]; the driver derives fx = W / (2 tan(hfov / 2)) from them. The
  // defaults are the Kinect / Xtion values (fx = fy = 575.8 px at 640 x 480).
  double horizontal_fov = 1.0145;
  double vertical_fov = 0.7898;
  bool with_color = true;
  uint16_t max_depth_mm = 10000;
};

// Field of view [rad] of a pinhole camera with focal length `focal_px` over `size_px` pixels.
double fieldOfView(double size_px, double focal_px);

class OniWriter {
 public:
  OniWriter() = default;
  ~OniWriter();  // closes (finalises) an open recording
  OniWriter(const OniWriter&) = delete;
  OniWriter& operator=(const OniWriter&) = delete;

  // Creates `path` and writes everything up to the first frame. False (see error()) on bad
  // options or I/O failure.
  bool open(const std::string& path, const OniRecordingOptions& options);
  // Appends one instant; its timestamp is frame_count() / fps seconds. The frame's size must
  // match the options and it must carry colour iff options.with_color.
  bool addFrame(const RgbdFrame& frame);
  // Writes the trailer and patches the header; the file is complete afterwards.
  bool close();

  bool isOpen() const { return file_.is_open(); }
  int frameCount() const { return frame_count_; }
  const std::string& error() const { return error_; }

 private:
  struct Node {
    uint32_t id = 0;
    uint32_t type = 0;  // 2 depth, 3 image
    uint64_t node_added_position = 0;
    uint64_t last_new_data_position = 0;
    std::vector<uint64_t> frame_positions;  // of each NEW_DATA record
  };

  bool fail(const std::string& message);
  uint64_t position();
  void writeRecord(uint32_t type, uint32_t node_id, uint64_t undo_position,
                   const std::string& fields, const void* payload, uint32_t payload_size);
  void writeNodeAdded(const Node& node, uint32_t frames, uint64_t max_timestamp,
                      uint64_t seek_table_position);
  void writeNodeProperties(const Node& node);
  void writeIntProperty(uint32_t node_id, const std::string& name, uint64_t value);
  void writeGeneralProperty(uint32_t node_id, const std::string& name, const std::string& data);
  uint64_t timestampOf(int frame_index) const;

  std::ofstream file_;
  OniRecordingOptions options_;
  std::vector<Node> nodes_;
  int frame_count_ = 0;
  std::string error_;
};

// Writes `frames` (all of options' size) as one recording; false with `error` set on failure.
bool writeOniFile(const std::string& path, const std::vector<RgbdFrame>& frames,
                  const OniRecordingOptions& options, std::string* error = nullptr);

}  // namespace sim
}  // namespace tabletop_shapes
