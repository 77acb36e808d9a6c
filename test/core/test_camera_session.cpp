// The camera driver's device handling (core/camera_session.h) with a fake camera on a fake
// clock, no master and no OpenNI2: a missing device, a device lost mid-run, streams that follow
// the subscribers, and a recording deleted, truncated or replaced while it plays.
#include "tabletop_shapes/core/camera_session.h"

#include "small_recording.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

namespace tabletop_shapes {
namespace {

using Clock = CameraSession::Clock;

// What the test scripts and observes: whether the camera is there, how many frames it still
// delivers, and what the session did with it.
struct FakeCameraState {
  Clock::time_point now{};  // the fake clock: waiting advances it
  bool present = true;
  int frames_left = -1;  // frames until the camera goes silent; -1: never
  bool has_color = true;
  int opens = 0, starts = 0, stops = 0;
  bool depth_running = false, color_running = false;
  std::vector<uint16_t> depth = std::vector<uint16_t>(4 * 3, 1000);
};

class FakeCamera : public CameraDevice {
 public:
  explicit FakeCamera(FakeCameraState& state) : state_(state) {}
  ~FakeCamera() override { stopStreams(); }
  bool isRecording() const override { return false; }
  std::string description() const override { return "Fake camera (fake://0)"; }
  void startStreams(bool depth, bool color, const CameraLog&) override {
    ++state_.starts;
    state_.depth_running = depth;
    state_.color_running = color && state_.has_color;
  }
  void stopStreams() override {
    if (!state_.depth_running && !state_.color_running) return;
    ++state_.stops;
    state_.depth_running = state_.color_running = false;
  }
  bool waitForFrame(int timeout_ms, CameraFrame* frame) override {
    if (!state_.depth_running || state_.frames_left == 0) {
      state_.now += std::chrono::milliseconds(timeout_ms);
      return false;
    }
    if (state_.frames_left > 0) --state_.frames_left;
    state_.now += std::chrono::milliseconds(33);
    frame->stream = CameraStream::kDepth;
    frame->width = 4;
    frame->height = 3;
    frame->data = state_.depth.data();
    frame->bytes = state_.depth.size() * 2;
    return true;
  }
  bool depthRegisteredToColor() const override { return false; }
  CameraStreamInfo streamInfo(CameraStream stream) const override {
    CameraStreamInfo info;
    info.running = stream == CameraStream::kDepth ? state_.depth_running : state_.color_running;
    return info;
  }

 private:
  FakeCameraState& state_;
};

class FakeBackend : public CameraBackend {
 public:
  explicit FakeBackend(FakeCameraState& state) : state_(state) {}
  std::unique_ptr<CameraDevice> open(const std::string&, std::string* problem) override {
    if (!state_.present) {
      *problem = "no OpenNI2 device is connected";
      return nullptr;
    }
    ++state_.opens;
    return std::make_unique<FakeCamera>(state_);
  }

 private:
  FakeCameraState& state_;
};

class CameraSessionTest : public ::testing::Test {
 protected:
  struct Message {
    bool error;
    std::string text;
  };
  std::unique_ptr<CameraSession> makeSession(const std::string& device_id) {
    CameraSessionOptions options;
    options.device_id = device_id;
    options.frame_timeout = 3.0;
    options.reconnect_max_interval = 10.0;
    options.problem_report_interval = 10.0;
    return std::make_unique<CameraSession>(
        backend_, options,
        [this](CameraLogLevel level, const std::string& text) {
          log_.push_back({level == CameraLogLevel::kError, text});
        },
        [this] { return state_.now; });
  }
  // Steps as the driver does (depth wanted, 100 ms waits), sleeping as the session asks.
  CameraSession::Step step(CameraSession& session) {
    CameraFrame frame;
    const CameraSession::Step result = session.step(true, false, false, 100, &frame);
    if (result.kind == CameraSession::Step::kRetry || result.kind == CameraSession::Step::kIdle)
      state_.now += std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(result.wait_seconds));
    if (result.kind == CameraSession::Step::kFrame) {
      EXPECT_EQ(frame.width, 4);
      EXPECT_EQ(frame.bytes, 24u);
    }
    return result;
  }
  std::vector<std::string> errors() const {
    std::vector<std::string> result;
    for (const Message& message : log_)
      if (message.error) result.push_back(message.text);
    return result;
  }
  bool logged(const std::string& text) const {
    for (const Message& message : log_)
      if (message.text == text) return true;
    return false;
  }
  // Steps until the session closes the silent device; returns the silent time in seconds.
  double stepUntilClosed(CameraSession& session) {
    const Clock::time_point start = state_.now;
    for (int i = 0; i < 1000 && session.isOpen(); ++i) step(session);
    return std::chrono::duration<double>(state_.now - start).count();
  }

  FakeCameraState state_;
  FakeBackend backend_{state_};
  std::vector<Message> log_;
};

TEST_F(CameraSessionTest, AMissingDeviceIsRetriedWithGrowingBackOffAndThrottledMessages) {
  state_.present = false;
  auto session = makeSession("");
  std::vector<double> waits;
  for (int i = 0; i < 8; ++i) {
    const CameraSession::Step result = step(*session);
    ASSERT_EQ(result.kind, CameraSession::Step::kRetry);
    waits.push_back(result.wait_seconds);
  }
  EXPECT_EQ(waits, (std::vector<double>{0.5, 1, 2, 4, 8, 10, 10, 10}));
  // Attempts at 0, 0.5, 1.5, 3.5, 7.5, 15.5, 25.5 and 35.5 s: the message at once, then when
  // more than 10 s have passed since it was last logged (15.5 and 35.5 s).
  EXPECT_EQ(errors(),
            (std::vector<std::string>{"no OpenNI2 device is connected; retrying in 0.5 s",
                                      "no OpenNI2 device is connected; retrying in 10.0 s",
                                      "no OpenNI2 device is connected; retrying in 10.0 s"}));
  EXPECT_EQ(state_.opens, 0);

  state_.present = true;  // plugged in
  EXPECT_EQ(step(*session).kind, CameraSession::Step::kFrame);
  EXPECT_TRUE(logged("the device is back"));
  EXPECT_TRUE(logged("opened Fake camera (fake://0)"));
  EXPECT_EQ(state_.opens, 1);
  // A later loss starts the back-off from 0.5 s again.
  session->close();
  state_.present = false;
  EXPECT_DOUBLE_EQ(step(*session).wait_seconds, 0.5);
}

TEST_F(CameraSessionTest, ALostDeviceIsClosedAfterTheFrameTimeoutAndReopened) {
  state_.frames_left = 5;
  auto session = makeSession("#1");
  for (int i = 0; i < 5; ++i) EXPECT_EQ(step(*session).kind, CameraSession::Step::kFrame);
  // Unplugged: silent. Open through 3 s of 100 ms waits, closed on the first wait past 3 s.
  for (int i = 0; i < 30; ++i) EXPECT_EQ(step(*session).kind, CameraSession::Step::kNoFrame);
  EXPECT_TRUE(session->isOpen());
  EXPECT_TRUE(errors().empty());
  EXPECT_NEAR(stepUntilClosed(*session), 0.1, 1e-9);
  EXPECT_FALSE(session->isOpen());
  EXPECT_EQ(state_.stops, 1);
  EXPECT_EQ(errors(), (std::vector<std::string>{"no frames from '#1' for 3.1 s: the camera was "
                                                "unplugged or stalled; reopening it"}));
  // Plugged in again: reopened at the next step, streaming again, said so.
  state_.frames_left = -1;
  const CameraSession::Step result = step(*session);
  EXPECT_EQ(result.kind, CameraSession::Step::kFrame);
  EXPECT_TRUE(result.streams_started);
  EXPECT_EQ(state_.opens, 2);
  EXPECT_EQ(state_.starts, 2);
  EXPECT_TRUE(logged("the device is back"));
}

TEST_F(CameraSessionTest, StreamsRunOnlyWhileSomeoneWantsThem) {
  auto session = makeSession("");
  CameraFrame frame;
  CameraSession::Step result = session->step(false, false, false, 100, &frame);
  EXPECT_EQ(result.kind, CameraSession::Step::kIdle);
  EXPECT_EQ(state_.starts, 0);
  result = session->step(true, false, false, 100, &frame);
  EXPECT_TRUE(result.streams_started);
  EXPECT_TRUE(state_.depth_running);
  EXPECT_FALSE(state_.color_running);
  EXPECT_TRUE(logged("streaming (someone subscribed)"));
  result = session->step(true, false, false, 100, &frame);  // the same set: no restart
  EXPECT_FALSE(result.streams_started);
  EXPECT_EQ(state_.starts, 1);
  result = session->step(true, true, false, 100, &frame);  // colour too
  EXPECT_TRUE(result.streams_started);
  EXPECT_TRUE(state_.color_running);
  result = session->step(true, true, true, 100, &frame);  // a mode changed
  EXPECT_TRUE(result.streams_started);
  EXPECT_EQ(state_.starts, 3);
  result = session->step(false, false, false, 100, &frame);
  EXPECT_EQ(result.kind, CameraSession::Step::kIdle);
  EXPECT_FALSE(state_.depth_running);
  EXPECT_TRUE(logged("no subscribers; streams stopped"));
  EXPECT_TRUE(session->isOpen());  // the device stays open while idle
  // A device without colour gives depth: wanting colour it lacks restarts nothing later.
  state_.has_color = false;
  session->step(true, true, false, 100, &frame);
  const int starts = state_.starts;
  EXPECT_EQ(session->step(true, true, false, 100, &frame).kind, CameraSession::Step::kFrame);
  EXPECT_EQ(state_.starts, starts);
}

// A recording played from a file: the session checks the file before every open, so a
// recording damaged under the player is named when the silent player is closed.
class RecordingSessionTest : public CameraSessionTest {
 protected:
  void SetUp() override { ASSERT_GT(bytes_.size(), 3000u); }
  // Plays, then the file changes and the player falls silent; returns the problem logged when
  // the session tries to reopen it, and checks that it recovers once the file is whole again.
  std::string problemAfter(const std::function<void()>& damage) {
    auto session = makeSession(path_);
    EXPECT_EQ(step(*session).kind, CameraSession::Step::kFrame);
    damage();
    state_.frames_left = 0;
    stepUntilClosed(*session);
    log_.clear();
    EXPECT_EQ(step(*session).kind, CameraSession::Step::kRetry);
    EXPECT_EQ(state_.opens, 1);  // the damaged file never reaches the player
    const std::vector<std::string> problems = errors();
    recording_.write(bytes_);
    state_.frames_left = -1;
    EXPECT_EQ(step(*session).kind, CameraSession::Step::kFrame);
    EXPECT_EQ(state_.opens, 2);
    return problems.size() == 1 ? problems[0] : "problems: " + std::to_string(problems.size());
  }

  testing_support::SmallRecordingFile recording_{"test_camera_session"};
  const std::string& path_ = recording_.path;
  const std::string& bytes_ = recording_.bytes;
};

TEST_F(RecordingSessionTest, ADeletedRecordingIsNamedAndPlaysAgainWhenBack) {
  EXPECT_EQ(problemAfter([this] { std::remove(path_.c_str()); }),
            "recording " + path_ + " does not exist or cannot be read; retrying in 0.5 s");
}

TEST_F(RecordingSessionTest, ATruncatedRecordingSaysWhereItEnds) {
  EXPECT_EQ(
      problemAfter([this] {
        recording_.write(bytes_.substr(0, 3000));
      }).rfind("recording " + path_ + " is truncated: it ends at byte 3000 inside record ", 0),
      0u);
}

TEST_F(RecordingSessionTest, ARecordingReplacedByAnotherFileIsNotAnOni) {
  EXPECT_EQ(problemAfter([this] { recording_.write("P6\n32 24\n255\n" + std::string(2304, 'x')); }),
            "recording " + path_ +
                " is not an .oni file (2317 bytes, no NI10 header); retrying in 0.5 s");
}

TEST_F(RecordingSessionTest, AFileThatIsNotAnOniNeverReachesThePlayer) {
  recording_.write("not a recording");
  auto session = makeSession(path_);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(step(*session).kind, CameraSession::Step::kRetry);
  EXPECT_EQ(state_.opens, 0);
  EXPECT_EQ(errors(), (std::vector<std::string>{"recording " + path_ +
                                                " is not an .oni file (15 bytes, no NI10 "
                                                "header); retrying in 0.5 s"}));
}

}  // namespace
}  // namespace tabletop_shapes
