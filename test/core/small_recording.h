// A small depth-only .oni recording (two 32 x 24 frames at 1 m) for the tests that damage one
// as a disk, a copy or a user would (test_oni_recording, test_camera_session).
#pragma once

#include "tabletop_shapes/sim/oni_writer.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <unistd.h>

namespace tabletop_shapes {
namespace testing_support {

// Writes it to `path` and returns its bytes (empty, with a test failure, when writing failed).
inline std::string writeSmallRecording(const std::string& path) {
  sim::RgbdFrame frame;
  frame.width = 32;
  frame.height = 24;
  frame.depth_mm.assign(32 * 24, 1000);
  sim::OniRecordingOptions options;
  options.width = 32;
  options.height = 24;
  options.with_color = false;
  std::string error;
  if (!sim::writeOniFile(path, {frame, frame}, options, &error)) {
    ADD_FAILURE() << error;
    return "";
  }
  std::ifstream file(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
}

// The recording in a file of the test's own (/tmp/<name>_<pid>.oni), removed at the end.
class SmallRecordingFile {
 public:
  explicit SmallRecordingFile(const std::string& name)
      : path("/tmp/" + name + "_" + std::to_string(getpid()) + ".oni"),
        bytes(writeSmallRecording(path)) {}
  ~SmallRecordingFile() { std::remove(path.c_str()); }
  // Replaces the file's content, as a disk, a copy or a user would.
  void write(const std::string& content) const {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << content;
  }

  const std::string path;
  const std::string bytes;  // as first written
};

}  // namespace testing_support
}  // namespace tabletop_shapes
