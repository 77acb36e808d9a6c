// The .oni writer (sim library, OpenNI2-free), checked by reading its recordings back through
// OpenNI2's own file driver: stream count, modes, field of view, frame count, timestamps and
// pixel values.
#include "tabletop_shapes/sim/oni_writer.h"

#include <OpenNI.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace tabletop_shapes {
namespace sim {
namespace {

class OniWriterTest : public ::testing::Test {
 protected:
  // OpenNI2 once per process: initialising it again after shutdown() crashes.
  static void SetUpTestSuite() { initialized_ = openni::OpenNI::initialize() == openni::STATUS_OK; }
  static void TearDownTestSuite() { openni::OpenNI::shutdown(); }
  void SetUp() override { ASSERT_TRUE(initialized_); }
  void TearDown() override { std::remove(path_.c_str()); }
  static inline bool initialized_ = false;
  // Frame f: depth 1000 + f mm everywhere except a marker pixel, colour (f, 2f, 3f) + marker.
  static RgbdFrame frame(int width, int height, int f, bool color) {
    RgbdFrame result;
    result.width = width;
    result.height = height;
    result.depth_mm.assign(static_cast<size_t>(width) * height, static_cast<uint16_t>(1000 + f));
    // Markers only where the frame has those pixels (the bad-size frames are smaller: writing
    // them anyway corrupted the heap, and the test died at exit under ctest).
    const bool has_markers = width > 5 && height > 7;
    if (has_markers) {
      result.depth_mm[7 * width + 5] = 4321;  // (u 5, v 7)
      result.depth_mm[width + 1] = 0;         // no reading
    }
    if (color) {
      result.rgb.resize(result.depth_mm.size() * 3);
      for (size_t i = 0; i < result.depth_mm.size(); ++i) {
        result.rgb[3 * i] = static_cast<uint8_t>(f);
        result.rgb[3 * i + 1] = static_cast<uint8_t>(2 * f);
        result.rgb[3 * i + 2] = static_cast<uint8_t>(3 * f);
      }
      if (has_markers) result.rgb[(7 * width + 5) * 3 + 1] = 222;
    }
    return result;
  }
  std::string path_ = "/tmp/test_oni_writer_" + std::to_string(getpid()) + ".oni";
};

TEST_F(OniWriterTest, RecordingReadsBackThroughOpenNI2) {
  OniRecordingOptions options;
  options.width = 160;
  options.height = 120;
  options.fps = 30;
  options.horizontal_fov = fieldOfView(160, 143.95);
  options.vertical_fov = fieldOfView(120, 143.95);
  std::vector<RgbdFrame> frames;
  for (int f = 0; f < 4; ++f) frames.push_back(frame(160, 120, f, true));
  std::string error;
  ASSERT_TRUE(writeOniFile(path_, frames, options, &error)) << error;

  openni::Device device;
  ASSERT_EQ(device.open(path_.c_str()), openni::STATUS_OK) << openni::OpenNI::getExtendedError();
  EXPECT_TRUE(device.isFile());
  device.getPlaybackControl()->setSpeed(-1.0f);  // manual: every frame, in order
  openni::VideoStream depth, color;
  ASSERT_EQ(depth.create(device, openni::SENSOR_DEPTH), openni::STATUS_OK);
  ASSERT_EQ(color.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
  EXPECT_EQ(device.getPlaybackControl()->getNumberOfFrames(depth), 4);
  EXPECT_EQ(device.getPlaybackControl()->getNumberOfFrames(color), 4);
  const openni::VideoMode mode = depth.getVideoMode();
  EXPECT_EQ(mode.getResolutionX(), 160);
  EXPECT_EQ(mode.getResolutionY(), 120);
  EXPECT_EQ(mode.getFps(), 30);
  EXPECT_EQ(mode.getPixelFormat(), openni::PIXEL_FORMAT_DEPTH_1_MM);
  EXPECT_EQ(color.getVideoMode().getPixelFormat(), openni::PIXEL_FORMAT_RGB888);
  // fx = W / (2 tan(hfov / 2)) recovers the focal length (OpenNI2 keeps the FOV as float).
  EXPECT_NEAR(160.0 / (2.0 * std::tan(depth.getHorizontalFieldOfView() / 2.0)), 143.95, 1e-3);
  EXPECT_NEAR(120.0 / (2.0 * std::tan(color.getVerticalFieldOfView() / 2.0)), 143.95, 1e-3);

  ASSERT_EQ(depth.start(), openni::STATUS_OK);
  ASSERT_EQ(color.start(), openni::STATUS_OK);
  openni::VideoStream* streams[] = {&depth, &color};
  int depth_frames = 0, color_frames = 0;
  for (int i = 0; i < 8; ++i) {
    int ready = -1;
    ASSERT_EQ(openni::OpenNI::waitForAnyStream(streams, 2, &ready, 2000), openni::STATUS_OK);
    openni::VideoFrameRef f;
    ASSERT_EQ(streams[ready]->readFrame(&f), openni::STATUS_OK);
    const int index = f.getFrameIndex() - 1;  // frame ids start at 1
    ASSERT_GE(index, 0);
    ASSERT_LT(index, 4);
    EXPECT_EQ(f.getTimestamp(), static_cast<uint64_t>(index) * 1000000 / 30);
    if (ready == 0) {
      ++depth_frames;
      ASSERT_EQ(f.getDataSize(), 160 * 120 * 2);
      const auto* data = static_cast<const uint16_t*>(f.getData());
      EXPECT_EQ(data[7 * 160 + 5], 4321);
      EXPECT_EQ(data[161], 0);
      EXPECT_EQ(data[0], 1000 + index);
    } else {
      ++color_frames;
      ASSERT_EQ(f.getDataSize(), 160 * 120 * 3);
      const auto* data = static_cast<const uint8_t*>(f.getData());
      EXPECT_EQ(data[0], index);
      EXPECT_EQ(data[2], 3 * index);
      EXPECT_EQ(data[(7 * 160 + 5) * 3 + 1], 222);
    }
  }
  EXPECT_EQ(depth_frames, 4);
  EXPECT_EQ(color_frames, 4);
  depth.stop();
  color.stop();
  std::this_thread::sleep_for(std::chrono::milliseconds(150));  // OpenNI2 needs it
  depth.destroy();
  color.destroy();
  device.close();
}

TEST_F(OniWriterTest, DepthOnlyRecordingHasNoColourStream) {
  OniRecordingOptions options;
  options.width = 64;
  options.height = 48;
  options.with_color = false;
  ASSERT_TRUE(writeOniFile(path_, {frame(64, 48, 0, false), frame(64, 48, 1, false)}, options));
  openni::Device device;
  ASSERT_EQ(device.open(path_.c_str()), openni::STATUS_OK);
  EXPECT_TRUE(device.hasSensor(openni::SENSOR_DEPTH));
  EXPECT_FALSE(device.hasSensor(openni::SENSOR_COLOR));
  // A depth stream too: OpenNI2 2.2 cancels the player thread of a file device closed without
  // ever creating a stream, and the process then crashed at exit unwinding it (1 run in 10).
  openni::VideoStream depth;
  ASSERT_EQ(depth.create(device, openni::SENSOR_DEPTH), openni::STATUS_OK);
  EXPECT_EQ(depth.getVideoMode().getResolutionX(), 64);
  openni::VideoStream color;
  EXPECT_NE(color.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
  depth.destroy();
  device.close();
}

TEST_F(OniWriterTest, RejectsBadInput) {
  OniWriter writer;
  OniRecordingOptions options;
  options.width = 0;
  EXPECT_FALSE(writer.open(path_, options));
  EXPECT_FALSE(writer.error().empty());
  options.width = 8;
  options.height = 6;
  EXPECT_FALSE(writer.open("/nonexistent_dir/x.oni", options));
  ASSERT_TRUE(writer.open(path_, options));
  EXPECT_FALSE(writer.addFrame(frame(4, 6, 0, true)));  // wrong size
  ASSERT_TRUE(writer.open(path_, options));
  EXPECT_FALSE(writer.addFrame(frame(8, 6, 0, false)));  // colour missing
}

TEST_F(OniWriterTest, FramesFromAnOrganisedCloud) {
  pcl::PointCloud<pcl::PointXYZRGB> cloud(3, 1);
  cloud[0].z = 1.2344f;
  cloud[0].r = 7;
  cloud[1].z = std::numeric_limits<float>::quiet_NaN();
  cloud[2].z = 70.0f;  // beyond 65535 mm
  const RgbdFrame f = rgbdFrameFromCloud(cloud);
  EXPECT_EQ(f.width, 3);
  EXPECT_EQ(f.height, 1);
  EXPECT_EQ(f.depth_mm, (std::vector<uint16_t>{1234, 0, 0}));
  EXPECT_EQ(f.rgb[0], 7);
}

}  // namespace
}  // namespace sim
}  // namespace tabletop_shapes
