// The OpenNI2 backend on a recording written by the sim library's .oni writer.
#include "tabletop_shapes/driver/openni2_camera.h"
#include "tabletop_shapes/sim/oni_writer.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <string>
#include <vector>

namespace tabletop_shapes {
namespace {

// The driver unloaded before anyone subscribed: the recording is opened, no stream is ever
// created, and OpenNI2 is shut down. OpenNI2 2.2 cancelled the file player's thread then, and the
// process crashed unwinding it in 4 runs of 5. Each run in its own process, since OpenNI2 cannot be
// initialised again after shutdown.
TEST(OpenNI2Camera, RecordingClosedBeforeAnyStreamShutsDownCleanly) {
  const std::string path = "/tmp/test_openni2_camera_" + std::to_string(getpid()) + ".oni";
  sim::OniRecordingOptions options;
  options.width = 64;
  options.height = 48;
  std::vector<sim::RgbdFrame> frames(2);
  for (sim::RgbdFrame& frame : frames) {
    frame.width = options.width;
    frame.height = options.height;
    frame.depth_mm.assign(static_cast<size_t>(frame.width) * frame.height, 1000);
    frame.rgb.assign(frame.depth_mm.size() * 3, 100);
  }
  std::string error;
  ASSERT_TRUE(sim::writeOniFile(path, frames, options, &error)) << error;

  constexpr int kRuns = 5;
  int clean_exits = 0;
  for (int run = 0; run < kRuns; ++run) {
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      int code = 0;
      {
        std::string init_error, problem;
        OpenNI2Backend backend(&init_error);
        if (!backend.initialized()) _exit(2);
        const std::unique_ptr<CameraDevice> camera = backend.open(path, &problem);
        if (!camera) _exit(3);
        if (!camera->isRecording()) code = 4;
      }  // camera closed, then OpenNI2 shut down
      _exit(code);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    EXPECT_TRUE(WIFEXITED(status))
        << "run " << run << " died with signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    if (WIFEXITED(status)) {
      EXPECT_EQ(WEXITSTATUS(status), 0) << "run " << run;
      clean_exits += WEXITSTATUS(status) == 0;
    }
  }
  EXPECT_EQ(clean_exits, kRuns);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace tabletop_shapes
