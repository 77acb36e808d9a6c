// A small depth-only .oni recording (two 32 x 24 frames at 1 m) for the tests that damage one
// as a disk, a copy or a user would (test_oni_recording, test_camera_session).
#pragma once

#include "tabletop_shapes/sim/oni_writer.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>

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

}  // namespace testing_support
}  // namespace tabletop_shapes
