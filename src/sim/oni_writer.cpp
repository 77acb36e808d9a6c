#include "tabletop_shapes/sim/oni_writer.h"

#include <cmath>
#include <cstring>

namespace tabletop_shapes {
namespace sim {
namespace {

// Record types and node types of the .oni format (OpenNI2 Source/Core/OniDataRecords.h).
constexpr uint32_t kRecordIntProperty = 3;
constexpr uint32_t kRecordGeneralProperty = 6;
constexpr uint32_t kRecordNodeRemoved = 7;
constexpr uint32_t kRecordNodeDataBegin = 8;
constexpr uint32_t kRecordNodeStateReady = 9;
constexpr uint32_t kRecordNewData = 10;
constexpr uint32_t kRecordEnd = 11;
constexpr uint32_t kRecordNodeAdded = 13;
constexpr uint32_t kRecordSeekTable = 14;
constexpr uint32_t kRecordMagic = 0x0052494E;  // "NIR\0"
constexpr uint32_t kRecordHeaderSize = 28;     // 5 x uint32 + uint64 undo position

constexpr uint32_t kNodeTypeDepth = 2;
constexpr uint32_t kNodeTypeImage = 3;
constexpr uint32_t kCodecUncompressed = 'N' | ('O' << 8) | ('N' << 16) | ('E' << 24);
// OpenNI 1.x pixel formats (xnPixelFormat) and OpenNI2 ones (oniPixelFormat).
constexpr uint32_t kXnPixelFormatRgb24 = 1;
constexpr uint32_t kXnPixelFormatGray16 = 4;
constexpr uint32_t kOniPixelFormatDepth1mm = 100;
constexpr uint32_t kOniPixelFormatRgb888 = 200;
constexpr uint64_t kFileHeaderMaxTimestampOffset = 12;

// Little-endian field serialisation (the format is packed, no padding).
template <typename T>
void append(std::string& out, T value) {
  for (size_t i = 0; i < sizeof(T); ++i) {
    out.push_back(static_cast<char>((static_cast<uint64_t>(value) >> (8 * i)) & 0xff));
  }
}
void appendDouble(std::string& out, double value) {
  uint64_t bits;
  std::memcpy(&bits, &value, sizeof(bits));
  append<uint64_t>(out, bits);
}
// uint32 length including the terminating NUL, then the bytes and the NUL.
void appendString(std::string& out, const std::string& text) {
  append<uint32_t>(out, static_cast<uint32_t>(text.size() + 1));
  out += text;
  out.push_back('\0');
}

}  // namespace

double fieldOfView(double size_px, double focal_px) {
  return 2.0 * std::atan(size_px / (2.0 * focal_px));
}

RgbdFrame rgbdFrameFromCloud(const pcl::PointCloud<pcl::PointXYZRGB>& cloud) {
  RgbdFrame frame;
  frame.width = static_cast<int>(cloud.width);
  frame.height = static_cast<int>(cloud.height);
  frame.depth_mm.resize(cloud.size(), 0);
  frame.rgb.resize(cloud.size() * 3, 0);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const auto& p = cloud[i];
    if (std::isfinite(p.z)) {
      const long mm = std::lround(p.z * 1000.0f);
      if (mm >= 1 && mm <= 65535) frame.depth_mm[i] = static_cast<uint16_t>(mm);
    }
    frame.rgb[3 * i] = p.r;
    frame.rgb[3 * i + 1] = p.g;
    frame.rgb[3 * i + 2] = p.b;
  }
  return frame;
}

OniWriter::~OniWriter() {
  if (isOpen()) close();
}

bool OniWriter::fail(const std::string& message) {
  error_ = message;
  if (file_.is_open()) file_.close();
  return false;
}

uint64_t OniWriter::position() { return static_cast<uint64_t>(file_.tellp()); }

uint64_t OniWriter::timestampOf(int frame_index) const {
  return static_cast<uint64_t>(frame_index) * 1000000ull / static_cast<uint64_t>(options_.fps);
}

void OniWriter::writeRecord(uint32_t type, uint32_t node_id, uint64_t undo_position,
                            const std::string& fields, const void* payload, uint32_t payload_size) {
  std::string header;
  append<uint32_t>(header, kRecordMagic);
  append<uint32_t>(header, type);
  append<uint32_t>(header, node_id);
  // The format's "fields size" counts the record header as well.
  append<uint32_t>(header, kRecordHeaderSize + static_cast<uint32_t>(fields.size()));
  append<uint32_t>(header, payload_size);
  append<uint64_t>(header, undo_position);
  file_.write(header.data(), static_cast<std::streamsize>(header.size()));
  file_.write(fields.data(), static_cast<std::streamsize>(fields.size()));
  if (payload_size > 0) {
    file_.write(static_cast<const char*>(payload), static_cast<std::streamsize>(payload_size));
  }
}

void OniWriter::writeNodeAdded(const Node& node, uint32_t frames, uint64_t max_timestamp,
                               uint64_t seek_table_position) {
  std::string fields;
  appendString(fields, node.type == kNodeTypeDepth ? "Depth" : "Image");
  append<uint32_t>(fields, node.type);
  append<uint32_t>(fields, kCodecUncompressed);
  append<uint32_t>(fields, frames);
  append<uint64_t>(fields, 0);  // min timestamp
  append<uint64_t>(fields, max_timestamp);
  append<uint64_t>(fields, seek_table_position);
  writeRecord(kRecordNodeAdded, node.id, 0, fields, nullptr, 0);
}

void OniWriter::writeGeneralProperty(uint32_t node_id, const std::string& name,
                                     const std::string& data) {
  std::string fields;
  appendString(fields, name);
  append<uint32_t>(fields, static_cast<uint32_t>(data.size()));
  fields += data;
  writeRecord(kRecordGeneralProperty, node_id, 0, fields, nullptr, 0);
}

void OniWriter::writeIntProperty(uint32_t node_id, const std::string& name, uint64_t value) {
  std::string fields;
  appendString(fields, name);
  append<uint32_t>(fields, 8);
  append<uint64_t>(fields, value);
  writeRecord(kRecordIntProperty, node_id, 0, fields, nullptr, 0);
}

void OniWriter::writeNodeProperties(const Node& node) {
  const bool depth = node.type == kNodeTypeDepth;
  const uint32_t bytes_per_pixel = depth ? 2 : 3;
  const uint32_t width = static_cast<uint32_t>(options_.width);
  const uint32_t height = static_cast<uint32_t>(options_.height);
  writeIntProperty(node.id, "oniRequiredFrameSize", width * height * bytes_per_pixel);
  writeIntProperty(node.id, "xnIsGenerating", 1);
  if (depth) writeIntProperty(node.id, "xnDeviceMaxDepth", options_.max_depth_mm);
  std::string mode;
  append<uint32_t>(mode, width);
  append<uint32_t>(mode, height);
  append<uint32_t>(mode, static_cast<uint32_t>(options_.fps));
  writeIntProperty(node.id, "xnSupportedMapOutputModesCount", 1);
  writeGeneralProperty(node.id, "xnSupportedMapOutputModes", mode);
  writeGeneralProperty(node.id, "xnMapOutputMode", mode);
  const uint32_t xn_format = depth ? kXnPixelFormatGray16 : kXnPixelFormatRgb24;
  std::string supported_formats;  // a bit field: bit (format - 1)
  append<uint32_t>(supported_formats, 1u << (xn_format - 1));
  writeGeneralProperty(node.id, "xnSupportedPixelFormats", supported_formats);
  writeIntProperty(node.id, "xnPixelFormat", xn_format);
  writeIntProperty(node.id, "oniPixelFormat",
                   depth ? kOniPixelFormatDepth1mm : kOniPixelFormatRgb888);
  std::string fov;
  appendDouble(fov, options_.horizontal_fov);
  appendDouble(fov, options_.vertical_fov);
  writeGeneralProperty(node.id, "xnFOV", fov);
  // libOniFile drops every frame of a stream without the cropping property.
  writeIntProperty(node.id, "Cropping", 1);
  std::string cropping;
  append<int32_t>(cropping, 0);  // disabled
  append<uint16_t>(cropping, 0);
  append<uint16_t>(cropping, 0);
  append<uint16_t>(cropping, static_cast<uint16_t>(width));
  append<uint16_t>(cropping, static_cast<uint16_t>(height));
  writeGeneralProperty(node.id, "xnCropping", cropping);
  writeIntProperty(node.id, "Mirror", 1);    // mirroring is a known property ...
  writeIntProperty(node.id, "xnMirror", 0);  // ... and off
}

bool OniWriter::open(const std::string& path, const OniRecordingOptions& options) {
  if (isOpen()) return fail("open(): a recording is already open");
  error_.clear();
  if (options.width <= 0 || options.height <= 0 || options.width > 65535 ||
      options.height > 65535 || options.fps <= 0 || !(options.horizontal_fov > 0.0) ||
      !(options.vertical_fov > 0.0)) {
    return fail("invalid recording options (size, fps or field of view)");
  }
  options_ = options;
  nodes_.clear();
  frame_count_ = 0;
  file_.open(path, std::ios::binary | std::ios::trunc | std::ios::out);
  if (!file_) return fail("cannot create " + path);

  nodes_.push_back(Node{1, kNodeTypeDepth, 0, 0, {}});
  if (options.with_color) nodes_.push_back(Node{2, kNodeTypeImage, 0, 0, {}});

  std::string header = "NI10";
  append<uint8_t>(header, 1);  // version 1.0.1.0
  append<uint8_t>(header, 0);
  append<uint16_t>(header, 1);
  append<uint32_t>(header, 0);
  append<uint64_t>(header, 0);  // max timestamp, patched on close()
  append<uint32_t>(header, static_cast<uint32_t>(nodes_.size()));  // max node id
  file_.write(header.data(), static_cast<std::streamsize>(header.size()));

  for (Node& node : nodes_) {
    node.node_added_position = position();
    writeNodeAdded(node, 0, 0, 0);  // patched on close()
    writeNodeProperties(node);
  }
  for (const Node& node : nodes_) {
    writeRecord(kRecordNodeStateReady, node.id, 0, "", nullptr, 0);
    std::string fields;
    append<uint32_t>(fields, 0xffffffffu);  // frame count and max timestamp: unknown yet,
    append<uint64_t>(fields, ~0ull);        // as OpenNI2's own recorder writes them
    writeRecord(kRecordNodeDataBegin, node.id, 0, fields, nullptr, 0);
  }
  if (!file_) return fail("write error on " + path);
  return true;
}

bool OniWriter::addFrame(const RgbdFrame& frame) {
  if (!isOpen()) return fail("addFrame(): no open recording");
  const size_t pixels = static_cast<size_t>(options_.width) * options_.height;
  if (frame.width != options_.width || frame.height != options_.height ||
      frame.depth_mm.size() != pixels) {
    return fail("addFrame(): frame size differs from the recording's");
  }
  if (options_.with_color != !frame.rgb.empty() ||
      (options_.with_color && frame.rgb.size() != pixels * 3)) {
    return fail("addFrame(): colour image missing, unexpected or of the wrong size");
  }
  const uint64_t timestamp = timestampOf(frame_count_);
  ++frame_count_;
  for (Node& node : nodes_) {
    const bool depth = node.type == kNodeTypeDepth;
    std::string fields;
    append<uint64_t>(fields, timestamp);
    append<uint32_t>(fields, static_cast<uint32_t>(frame_count_));  // frame ids start at 1
    const uint64_t record_position = position();
    const void* data = depth ? static_cast<const void*>(frame.depth_mm.data())
                             : static_cast<const void*>(frame.rgb.data());
    const uint32_t size = static_cast<uint32_t>(depth ? pixels * 2 : pixels * 3);
    // uint16 depth is written in host order: the format is little-endian, as is x86 / ARM.
    writeRecord(kRecordNewData, node.id, node.last_new_data_position, fields, data, size);
    node.last_new_data_position = record_position;
    node.frame_positions.push_back(record_position);
  }
  if (!file_) return fail("write error while adding a frame");
  return true;
}

bool OniWriter::close() {
  if (!isOpen()) return fail("close(): no open recording");
  const uint64_t max_timestamp = frame_count_ > 0 ? timestampOf(frame_count_ - 1) : 0;
  std::vector<uint64_t> seek_table_positions;
  for (const Node& node : nodes_) {
    writeRecord(kRecordNodeRemoved, node.id, node.node_added_position, "", nullptr, 0);
    seek_table_positions.push_back(position());
    std::string table;  // entry 0 is empty: frame ids start at 1
    append<uint64_t>(table, 0);
    append<uint32_t>(table, 0);
    append<uint64_t>(table, 0);
    for (size_t i = 0; i < node.frame_positions.size(); ++i) {
      append<uint64_t>(table, timestampOf(static_cast<int>(i)));
      append<uint32_t>(table, 0);  // configuration id
      append<uint64_t>(table, node.frame_positions[i]);
    }
    writeRecord(kRecordSeekTable, node.id, 0, "", table.data(),
                static_cast<uint32_t>(table.size()));
  }
  writeRecord(kRecordEnd, 0, 0, "", nullptr, 0);
  // Patch the node records (same size) and the header's max timestamp.
  for (size_t i = 0; i < nodes_.size(); ++i) {
    file_.seekp(static_cast<std::streamoff>(nodes_[i].node_added_position));
    writeNodeAdded(nodes_[i], static_cast<uint32_t>(frame_count_), max_timestamp,
                   seek_table_positions[i]);
  }
  std::string header_timestamp;
  append<uint64_t>(header_timestamp, max_timestamp);
  file_.seekp(static_cast<std::streamoff>(kFileHeaderMaxTimestampOffset));
  file_.write(header_timestamp.data(), 8);
  const bool ok = static_cast<bool>(file_);
  file_.close();
  if (!ok) return fail("write error while finishing the recording");
  return true;
}

bool writeOniFile(const std::string& path, const std::vector<RgbdFrame>& frames,
                  const OniRecordingOptions& options, std::string* error) {
  OniWriter writer;
  bool ok = writer.open(path, options);
  for (size_t i = 0; ok && i < frames.size(); ++i) ok = writer.addFrame(frames[i]);
  if (ok) ok = writer.close();
  if (!ok && error) *error = writer.error();
  return ok;
}

}  // namespace sim
}  // namespace tabletop_shapes
