// The stages' tf2 lookups without a master (issue 16, TF rows): a transform that jumps between
// frames is taken at each frame's own stamp, and stamps going back (a looped bag) are reported
// and, beyond tf2's cache time, let the buffer take the new transforms again, static ones kept.
#include "tabletop_shapes/ros/frame_transforms.h"
#include "tabletop_shapes/ros/stage_monitor.h"

#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

namespace tabletop_shapes {
namespace {

geometry_msgs::TransformStamped transform(const std::string& parent, const std::string& child,
                                          double x, double stamp_seconds) {
  geometry_msgs::TransformStamped t;
  t.header.frame_id = parent;
  t.header.stamp = ros::Time(stamp_seconds);
  t.child_frame_id = child;
  t.transform.translation.x = x;
  t.transform.rotation.w = 1.0;
  return t;
}

class FrameTransformsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // The wait of a lookup is 0 s here; without this tf2 logs an error for every timed lookup.
    transforms_.buffer().setUsingDedicatedThread(true);
    // camera 0.5 m along base_link's x, static; base_link moves in world
    ASSERT_TRUE(transforms_.buffer().setTransform(transform("base_link", "camera", 0.5, 0.0),
                                                  "test", /*is_static=*/true));
  }
  bool move(double x, double stamp) {
    return transforms_.buffer().setTransform(transform("world", "base_link", x, stamp), "test");
  }
  double cameraX(double stamp) {
    return transforms_.lookup("world", "camera", ros::Time(stamp)).translation().x();
  }

  std::vector<std::string> jumps_;
  // No listener here: nothing fills the buffer while a lookup waits, so no wait.
  bridge::FrameTransforms transforms_{ros::Duration(0.0),
                                      [this](const std::string& text) { jumps_.push_back(text); }};
};

TEST_F(FrameTransformsTest, AJumpingTransformIsTakenAtEachFramesOwnStamp) {
  ASSERT_TRUE(move(0.0, 100.0));
  ASSERT_TRUE(move(3.0, 101.0));
  ASSERT_TRUE(move(0.0, 102.0));
  EXPECT_DOUBLE_EQ(cameraX(100.0), 0.5);
  EXPECT_DOUBLE_EQ(cameraX(101.0), 3.5);
  EXPECT_DOUBLE_EQ(cameraX(102.0), 0.5);
  EXPECT_TRUE(jumps_.empty());
}

TEST_F(FrameTransformsTest, AFrameWithoutItsTransformThrowsNamingTheGap) {
  ASSERT_TRUE(move(0.0, 100.0));
  try {
    cameraX(105.0);
    FAIL() << "no transform at 105 s: expected an exception";
  } catch (const tf2::TransformException& error) {
    EXPECT_NE(std::string(error.what()).find("Lookup would require extrapolation at time 105"),
              std::string::npos)
        << error.what();
  }
}

TEST_F(FrameTransformsTest, StampsGoingBackBeyondTheCacheTimeEmptyTheBufferButNotStaticOnes) {
  ASSERT_TRUE(move(1.0, 100.0));
  ASSERT_TRUE(move(1.0, 101.0));
  EXPECT_DOUBLE_EQ(cameraX(101.0), 1.5);
  // A bag looped after 31 s: tf2 alone refuses its transforms as older than its newest.
  EXPECT_FALSE(move(2.0, 70.0)) << "tf2 keeps transforms within its cache time only";
  EXPECT_THROW(cameraX(70.0), tf2::TransformException);  // reports and empties the buffer
  ASSERT_EQ(jumps_.size(), 1u);
  EXPECT_EQ(jumps_[0],
            "frame stamps went back 31.000 s (from 101.000 to 70.000; a bag played in a loop?): "
            "more than tf's cache time, transforms received before dropped (static ones kept)");
  ASSERT_TRUE(move(2.0, 70.5)) << "taken again";
  ASSERT_TRUE(move(2.0, 71.0));
  EXPECT_DOUBLE_EQ(cameraX(70.5), 2.5) << "base_link -> camera (static) is still there";
  EXPECT_EQ(jumps_.size(), 1u) << "one jump, one report";
}

TEST_F(FrameTransformsTest, StampsGoingBackWithinTheCacheTimeKeepTheTransforms) {
  for (double stamp : {100.0, 101.0, 102.0, 103.0}) ASSERT_TRUE(move(stamp - 100.0, stamp));
  EXPECT_DOUBLE_EQ(cameraX(103.0), 3.5);
  EXPECT_DOUBLE_EQ(cameraX(101.0), 1.5) << "2 s back: tf2 still holds these";
  ASSERT_EQ(jumps_.size(), 1u);
  EXPECT_EQ(jumps_[0],
            "frame stamps went back 2.000 s (from 103.000 to 101.000; a bag played in a loop?)");
}

// The stage's log throttle: a looped bag logs "stamps went back" between the "no transform"
// lines of the frames; each reason stays throttled on its own (before, the last reason only was
// remembered, and two alternating reasons were both logged with every frame).
TEST(ReasonThrottle, AlternatingReasonsAreEachThrottled) {
  bridge::ReasonThrottle throttle(60.0);
  int logged = 0;
  for (int frame = 0; frame < 10; ++frame) {
    logged += throttle.shouldLog("no transform to map");
    logged += throttle.shouldLog("frame stamps went back");
  }
  EXPECT_EQ(logged, 2);
  EXPECT_TRUE(throttle.shouldLog("a third problem"));
}

TEST(ReasonThrottle, AReasonIsLoggedAgainAfterItsPeriod) {
  bridge::ReasonThrottle throttle(0.05);
  EXPECT_TRUE(throttle.shouldLog("no transform to map"));
  EXPECT_FALSE(throttle.shouldLog("no transform to map"));
  std::this_thread::sleep_for(std::chrono::milliseconds(80));
  EXPECT_TRUE(throttle.shouldLog("no transform to map"));
}

}  // namespace
}  // namespace tabletop_shapes
