// Per-stage bookkeeping shared by the nodelets: processing time per frame and skipped frames,
// reported as diagnostic_msgs/DiagnosticArray on /diagnostics once per second, and a check
// that clouds really travel between the nodelets without a copy (see markPublished).
#pragma once

#include <boost/shared_ptr.hpp>
#include <ros/ros.h>

#include <chrono>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace tabletop_shapes {
namespace bridge {

// Zero-copy bookkeeping: every cloud a nodelet of this library publishes is remembered (weakly,
// the last few dozen). A subscriber in the same process that receives the very same object
// got it by pointer; a cloud that was serialised and deserialised on the way (another process,
// or a type mismatch) is a different object. Process-wide, thread-safe.
void markPublished(const boost::shared_ptr<const void>& cloud);
bool wasPublishedInProcess(const void* cloud);

// Throttling by reason: each reason is logged at once the first time and then at most once per
// period while it repeats, also when other reasons come in between (a looped bag's "stamps went
// back" between "no transform" lines). ROS's *_THROTTLE macros throttle per call site, which
// would hide a second, different problem behind the first.
class ReasonThrottle {
 public:
  explicit ReasonThrottle(double period_seconds) : period_(period_seconds) {}
  bool shouldLog(const std::string& reason);

 private:
  // Reasons are few (a key per kind of problem); the map is pruned of expired ones when large.
  static constexpr size_t kPruneAbove = 64;
  double period_;
  std::map<std::string, std::chrono::steady_clock::time_point> last_logged_;
  std::mutex mutex_;
};

// A problem with a frame, as the nodelet's log shows it.
struct Problem {
  enum class Level { Warn, Error };
  Level level = Level::Warn;
  std::string log_text;      // the line logged
  std::string throttle_key;  // repeats within 5 s are not logged again (empty: log_text)
};

class StageMonitor {
 public:
  // `name`: the nodelet's name (the diagnostic status is "<name>: processing").
  StageMonitor(ros::NodeHandle& node, const std::string& name);

  // Counts a cloud received from the previous stage as shared (zero-copy) or copied.
  void countInput(const void* cloud);
  // Frames dropped at this stage's input queue: every stage numbers the frames it publishes
  // (the cloud header's seq, 1, 2, 3, ...), so a gap in the numbers the next stage receives is
  // the count it lost. A number at or below the last one (a restart, a looped bag, a publisher
  // that does not number its frames) starts the count afresh.
  void countSequence(uint32_t seq);
  // One frame fully processed in `milliseconds`.
  void frameDone(double milliseconds, size_t points_in, size_t points_out);
  // A frame dropped without output (missing transform, invalid cloud), with the reason shown
  // in the diagnostics, and the problem logged (throttled by its key).
  void frameSkipped(const std::string& reason, const Problem& problem);
  // A frame refused because the chain was busy (Preprocess's admission, ros/frame_admission.h):
  // counted as `frames skipped: chain busy`, apart from `frames skipped`, and neither logged
  // nor a WARN: at a camera's rate it is the chain working as intended.
  void frameSkippedBusy();
  // A frame processed, but with nothing found (no table), with the reason; call frameDone too.
  void frameWithoutResult(const std::string& reason, const Problem& problem);
  // An input topic (its resolved name and ROS type): while no input at all has arrived
  // kSilentInputSeconds after start, /diagnostics (WARN) and the log (throttled) name each such
  // topic and its publishers as the master lists them: none (a wrong name or remapping), or of
  // another type. Otherwise a wrong topic name gets no answer at all.
  void expectInput(const std::string& resolved_topic, const std::string& type);
  template <typename Message>
  void expectInput(const ros::Subscriber& subscriber) {
    expectInput(subscriber.getTopic(), ros::message_traits::datatype<Message>());
  }
  // A standing warning under `key` (e.g. "up": the given up disagrees with the scene): level
  // WARN on /diagnostics and a throttled log line while set; an empty `text` clears it.
  void setWarning(const std::string& key, const std::string& text);
  // A problem that is no frame's (e.g. frame stamps going back), logged throttled by its key.
  void log(const Problem& problem);

  static constexpr double kSilentInputSeconds = 5.0;

 private:
  void publish(const ros::SteadyTimerEvent&);
  // "no input for N s since start: ..." when silent long enough (asks the master), else "".
  std::string silentInputWarning();

  std::string name_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::vector<std::pair<std::string, std::string>> expected_inputs_;  // topic, type
  bool input_seen_ = false;
  std::string silent_text_;  // the last master query's answer, refreshed every 5 s
  std::chrono::steady_clock::time_point silent_checked_;
  struct StandingWarning {
    std::string text;
    std::chrono::steady_clock::time_point logged;
  };
  std::map<std::string, StandingWarning> warnings_;  // setWarning, by key
  ReasonThrottle log_throttle_{5.0};
  ros::Publisher publisher_;
  ros::SteadyTimer timer_;
  std::mutex mutex_;
  // totals
  uint64_t frames_ = 0, skipped_ = 0, without_result_ = 0, inputs_shared_ = 0, inputs_copied_ = 0;
  uint64_t dropped_ = 0, skipped_busy_ = 0;
  uint32_t last_seq_ = 0;
  double usual_rss_mb_ = 0.0;  // the process's RSS, slowly averaged
  double last_ms_ = 0.0;
  size_t last_points_in_ = 0, last_points_out_ = 0;
  std::string last_skip_reason_, last_no_result_reason_;
  // since the last report
  uint64_t window_frames_ = 0, window_skipped_ = 0, window_without_result_ = 0;
  double window_sum_ms_ = 0.0, window_max_ms_ = 0.0;
};

// Wall-clock stopwatch in milliseconds.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double milliseconds() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_)
        .count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace bridge
}  // namespace tabletop_shapes
