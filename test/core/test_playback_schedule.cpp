// The driver's playback pacing (core/playback_schedule.h) with a clock of the test's own: a
// recording's frames are due at the recorded rate, loops continue the schedule (also a one-frame
// recording, whose every loop repeats one device time: `make soak`'s latency grew with run time
// because its stamps stood still), depth and colour of one instant share their due time.
#include "tabletop_shapes/core/playback_schedule.h"

#include <gtest/gtest.h>

namespace tabletop_shapes {
namespace {

using Clock = PlaybackSchedule::Clock;
using std::chrono::microseconds;

constexpr int kPeriodUs = 33333;
constexpr int kDepth = 0, kColour = 1;

double microsecondsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

TEST(PlaybackSchedule, FramesAreDueAtTheRecordedRate) {
  PlaybackSchedule schedule;
  schedule.configure(kPeriodUs, 1.0);
  const Clock::time_point start = Clock::now();
  const auto first = schedule.schedule(kDepth, 1000, start);
  EXPECT_TRUE(first.restarted);
  EXPECT_EQ(first.due, start);
  // Delivered at once (the player does not wait): due one and two periods later.
  const auto second = schedule.schedule(kDepth, 1000 + kPeriodUs, start);
  const auto third = schedule.schedule(kDepth, 1000 + 2 * kPeriodUs, start);
  EXPECT_FALSE(second.restarted);
  EXPECT_NEAR(microsecondsBetween(start, second.due), kPeriodUs, 1.0);
  EXPECT_NEAR(microsecondsBetween(start, third.due), 2 * kPeriodUs, 1.0);
}

TEST(PlaybackSchedule, SpeedScalesTheRate) {
  PlaybackSchedule schedule;
  schedule.configure(kPeriodUs, 2.0);
  const Clock::time_point start = Clock::now();
  schedule.schedule(kDepth, 0, start);
  EXPECT_NEAR(microsecondsBetween(start, schedule.schedule(kDepth, kPeriodUs, start).due),
              kPeriodUs / 2.0, 1.0);
}

// The bundled paper_scene.oni holds one frame: every loop delivers the same device time. Each
// must be due one period after the previous one, not all at the first one's time.
TEST(PlaybackSchedule, AOneFrameRecordingAdvancesOnePeriodPerLoop) {
  PlaybackSchedule schedule;
  schedule.configure(kPeriodUs, 1.0);
  const Clock::time_point start = Clock::now();
  Clock::time_point previous = schedule.schedule(kDepth, 5000, start).due;
  EXPECT_EQ(schedule.schedule(kColour, 5000, start).due, previous);  // same instant
  for (int loop = 1; loop <= 100; ++loop) {
    const Clock::time_point now = previous;  // the driver slept until the last frame was due
    const auto depth = schedule.schedule(kDepth, 5000, now);
    const auto colour = schedule.schedule(kColour, 5000, now);
    EXPECT_TRUE(depth.restarted);
    EXPECT_FALSE(colour.restarted);
    EXPECT_EQ(colour.due, depth.due);
    ASSERT_NEAR(microsecondsBetween(previous, depth.due), kPeriodUs, 1.0) << "loop " << loop;
    previous = depth.due;
  }
  EXPECT_NEAR(microsecondsBetween(start, previous), 100.0 * kPeriodUs, 100.0);
}

TEST(PlaybackSchedule, ALongRecordingLoopsOnePeriodAfterItsLastFrame) {
  PlaybackSchedule schedule;
  schedule.configure(kPeriodUs, 1.0);
  const Clock::time_point start = Clock::now();
  Clock::time_point last;
  for (int f = 0; f < 20; ++f) last = schedule.schedule(kDepth, uint64_t(f) * kPeriodUs, start).due;
  // Colour lags: the new loop's first depth frame comes before the old loop's last colour one.
  const auto loop_depth = schedule.schedule(kDepth, 0, last);
  EXPECT_TRUE(loop_depth.restarted);
  EXPECT_NEAR(microsecondsBetween(last, loop_depth.due), kPeriodUs, 1.0);
  const auto late_colour = schedule.schedule(kColour, 19ull * kPeriodUs, last);
  EXPECT_FALSE(late_colour.restarted);
  EXPECT_LE(late_colour.due, loop_depth.due);  // due already: it does not hold the loop back
  const auto next = schedule.schedule(kDepth, kPeriodUs, last);
  EXPECT_FALSE(next.restarted);
  EXPECT_NEAR(microsecondsBetween(loop_depth.due, next.due), kPeriodUs, 1.0);
}

TEST(PlaybackSchedule, AScheduleFarBehindRestartsFromNow) {
  PlaybackSchedule schedule;
  schedule.configure(kPeriodUs, 1.0);
  const Clock::time_point start = Clock::now();
  schedule.schedule(kDepth, 0, start);
  const Clock::time_point late = start + std::chrono::seconds(5);  // the driver was stalled
  const auto looped = schedule.schedule(kDepth, 0, late);
  EXPECT_TRUE(looped.restarted);
  EXPECT_EQ(looped.due, late);
}

TEST(PlaybackSchedule, ResetBeginsANewSchedule) {
  PlaybackSchedule schedule;
  schedule.configure(kPeriodUs, 1.0);
  const Clock::time_point start = Clock::now();
  schedule.schedule(kDepth, 0, start);
  schedule.schedule(kDepth, kPeriodUs, start);
  schedule.reset();
  const Clock::time_point later = start + std::chrono::milliseconds(300);
  const auto first = schedule.schedule(kDepth, 2 * kPeriodUs, later);
  EXPECT_TRUE(first.restarted);
  EXPECT_EQ(first.due, later);
}

}  // namespace
}  // namespace tabletop_shapes
