#include "tabletop_shapes/core/oni_recording.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <fstream>

namespace tabletop_shapes {

bool looksLikeRecording(const std::string& device_id) {
  const std::string suffix = ".oni";
  return device_id.size() > suffix.size() &&
         std::equal(suffix.rbegin(), suffix.rend(), device_id.rbegin(), [](char a, char b) {
           return a == std::tolower(static_cast<unsigned char>(b));  // a: the suffix, lower case
         });
}

std::string oniRecordingProblem(std::istream& in, uint64_t size, const std::string& name) {
  constexpr uint64_t kHeaderSize = 24, kRecordHeaderSize = 28;
  constexpr uint32_t kRecordMagic = 0x0052494E;  // "NIR\0", little-endian
  constexpr uint32_t kEndRecord = 11;
  char magic[4] = {};
  in.seekg(0);
  in.read(magic, 4);
  if (size < kHeaderSize || !in || std::memcmp(magic, "NI10", 4) != 0) {
    return name + " is not an .oni file (" + std::to_string(size) + " bytes, no NI10 header)";
  }
  // Each record header: magic, type, node id, header size, payload size (then undo position).
  uint64_t offset = kHeaderSize;
  for (int record = 1;; ++record) {
    if (offset + kRecordHeaderSize > size) {
      return name + " is truncated: it ends at byte " + std::to_string(size) + " inside record " +
             std::to_string(record) + " (no END record)";
    }
    uint32_t header[5];
    in.seekg(static_cast<std::streamoff>(offset));
    in.read(reinterpret_cast<char*>(header), sizeof(header));
    if (!in || header[0] != kRecordMagic || header[3] < kRecordHeaderSize) {
      return name + " is damaged: no valid record at byte " + std::to_string(offset);
    }
    if (header[1] == kEndRecord) return "";
    offset += static_cast<uint64_t>(header[3]) + header[4];
  }
}

std::string oniRecordingProblem(const std::string& path) {
  const std::string name = "recording " + path;
  std::ifstream file(path, std::ios::binary | std::ios::ate);
  if (!file) return name + " does not exist or cannot be read";
  const auto end = file.tellg();
  if (end < 0) return name + " cannot be read (no size)";
  return oniRecordingProblem(file, static_cast<uint64_t>(end), name);
}

}  // namespace tabletop_shapes
