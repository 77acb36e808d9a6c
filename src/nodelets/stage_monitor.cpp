#include "tabletop_shapes/ros/stage_monitor.h"

#include <boost/weak_ptr.hpp>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <malloc.h>
#include <ros/master.h>

#include <algorithm>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <sstream>

namespace tabletop_shapes {
namespace bridge {
namespace {

// A cloud stays in the registry until 64 newer ones were published: far longer than a
// subscriber queue holds it.
constexpr size_t kRememberedClouds = 64;
// A standing warning is logged again this often while it stands [s].
constexpr double kWarningLogPeriod = 10.0;

struct PublishedCloud {
  const void* address;
  boost::weak_ptr<const void> alive;
};

std::mutex registry_mutex;
std::deque<PublishedCloud> registry;

diagnostic_msgs::KeyValue keyValue(const std::string& key, const std::string& value) {
  diagnostic_msgs::KeyValue entry;
  entry.key = key;
  entry.value = value;
  return entry;
}

template <typename T>
diagnostic_msgs::KeyValue keyValue(const std::string& key, T value) {
  std::ostringstream text;
  text << value;
  return keyValue(key, text.str());
}

// The process's resident memory (all nodelets of a manager together), from /proc.
double residentMegabytes() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);) {
    if (line.compare(0, 6, "VmRSS:") == 0) return std::atof(line.c_str() + 6) / 1024.0;
  }
  return 0.0;
}

// After a burst (a cloud of millions of points, processed or refused) glibc keeps the freed
// memory in its arenas for good: the manager stayed at 490-600 MB instead of ~110 MB. When the
// process is far above its usual size, give the free memory back. Returns the RSS after.
double releaseMemoryAfterBurst(double& usual_mb) {
  constexpr double kBurstMb = 48.0;
  double rss = residentMegabytes();
  if (usual_mb > 0.0 && rss > usual_mb + kBurstMb) {
    malloc_trim(0);
    rss = residentMegabytes();
  }
  usual_mb = usual_mb > 0.0 ? usual_mb + 0.05 * (rss - usual_mb) : rss;  // follows slowly
  return rss;
}

// Who publishes `topic` according to the master, and whether the type fits `type`.
std::string describePublishers(const std::string& topic, const std::string& type) {
  XmlRpc::XmlRpcValue args, result, state;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, state, false)) {
    return topic + ": the master does not answer";
  }
  std::string publishers;
  XmlRpc::XmlRpcValue& published = state[0];
  for (int i = 0; i < published.size(); ++i) {
    if (static_cast<std::string>(published[i][0]) != topic) continue;
    for (int j = 0; j < published[i][1].size(); ++j) {
      publishers += (publishers.empty() ? "" : ", ") + static_cast<std::string>(published[i][1][j]);
    }
  }
  if (publishers.empty()) {
    return topic + " (" + type + ") has no publisher: a wrong topic name or remapping? " +
           "(rostopic list shows what is published)";
  }
  ros::master::V_TopicInfo topics;
  ros::master::getTopics(topics);
  for (const ros::master::TopicInfo& info : topics) {
    if (info.name == topic && info.datatype != type && info.datatype != "*") {
      return topic + " is published as " + info.datatype + " by " + publishers +
             ", but this stage reads " + type;
    }
  }
  return topic + " (" + type + ") is published by " + publishers + ", but nothing arrived";
}

}  // namespace

void markPublished(const boost::shared_ptr<const void>& cloud) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  registry.push_back({cloud.get(), cloud});
  while (registry.size() > kRememberedClouds) registry.pop_front();
}

bool wasPublishedInProcess(const void* cloud) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  // While the published object is alive (not expired) no other object can have its address.
  return std::any_of(registry.begin(), registry.end(), [&](const PublishedCloud& entry) {
    return entry.address == cloud && !entry.alive.expired();
  });
}

StageMonitor::StageMonitor(ros::NodeHandle& node, const std::string& name) : name_(name) {
  publisher_ = node.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
  timer_ = node.createSteadyTimer(ros::WallDuration(1.0), &StageMonitor::publish, this);
}

void StageMonitor::countInput(const void* cloud) {
  const bool shared = wasPublishedInProcess(cloud);
  std::lock_guard<std::mutex> lock(mutex_);
  input_seen_ = true;
  ++(shared ? inputs_shared_ : inputs_copied_);
}

void StageMonitor::countSequence(uint32_t seq) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (seq > last_seq_ && last_seq_ > 0) dropped_ += seq - last_seq_ - 1;
  last_seq_ = seq;
}

void StageMonitor::frameDone(double milliseconds, size_t points_in, size_t points_out) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++frames_;
  ++window_frames_;
  last_ms_ = milliseconds;
  last_points_in_ = points_in;
  last_points_out_ = points_out;
  window_sum_ms_ += milliseconds;
  window_max_ms_ = std::max(window_max_ms_, milliseconds);
}

void StageMonitor::frameSkipped(const std::string& reason, const Problem& problem) {
  log(problem);
  std::lock_guard<std::mutex> lock(mutex_);
  input_seen_ = true;
  ++skipped_;
  ++window_skipped_;
  last_skip_reason_ = reason;
}

void StageMonitor::frameSkippedBusy() {
  std::lock_guard<std::mutex> lock(mutex_);
  input_seen_ = true;
  ++skipped_busy_;
}

void StageMonitor::frameWithoutResult(const std::string& reason, const Problem& problem) {
  log(problem);
  std::lock_guard<std::mutex> lock(mutex_);
  ++without_result_;
  ++window_without_result_;
  last_no_result_reason_ = reason;
}

void StageMonitor::expectInput(const std::string& resolved_topic, const std::string& type) {
  std::lock_guard<std::mutex> lock(mutex_);
  expected_inputs_.emplace_back(resolved_topic, type);
}

void StageMonitor::setWarning(const std::string& key, const std::string& text) {
  const auto now = std::chrono::steady_clock::now();
  bool log_it = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (text.empty()) {
      warnings_.erase(key);
      return;
    }
    auto [entry, added] = warnings_.try_emplace(key);
    // Logged when new or changed, then every kWarningLogPeriod while it stands; each key on
    // its own, so that standing warnings and per-frame problems do not unthrottle each other.
    log_it = added || entry->second.text != text ||
             std::chrono::duration<double>(now - entry->second.logged).count() >= kWarningLogPeriod;
    entry->second.text = text;
    if (log_it) entry->second.logged = now;
  }
  if (log_it) ROS_WARN_NAMED(name_, "%s", text.c_str());
}

std::string StageMonitor::silentInputWarning() {
  std::vector<std::pair<std::string, std::string>> inputs;
  const auto now = std::chrono::steady_clock::now();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const double silent = std::chrono::duration<double>(now - start_).count();
    if (input_seen_ || expected_inputs_.empty() || silent < kSilentInputSeconds) return "";
    if (!silent_text_.empty() &&
        std::chrono::duration<double>(now - silent_checked_).count() < 5.0) {
      return silent_text_;
    }
    inputs = expected_inputs_;
  }
  // The master is asked outside the lock: frames may arrive meanwhile.
  std::ostringstream text;
  text << "no input since start (" << static_cast<int>(kSilentInputSeconds) << "+ s): ";
  for (size_t i = 0; i < inputs.size(); ++i) {
    text << (i ? "; " : "") << describePublishers(inputs[i].first, inputs[i].second);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  silent_text_ = text.str();
  silent_checked_ = now;
  return silent_text_;
}

// Under the nodelet's logger name, as NODELET_WARN / NODELET_ERROR log.
void StageMonitor::log(const Problem& problem) {
  if (!log_throttle_.shouldLog(problem.throttle_key.empty() ? problem.log_text
                                                            : problem.throttle_key)) {
    return;
  }
  if (problem.level == Problem::Level::Error) {
    ROS_ERROR_NAMED(name_, "%s", problem.log_text.c_str());
  } else {
    ROS_WARN_NAMED(name_, "%s", problem.log_text.c_str());
  }
}

bool ReasonThrottle::shouldLog(const std::string& reason) {
  const auto now = std::chrono::steady_clock::now();
  const auto expired = [&](std::chrono::steady_clock::time_point logged) {
    return std::chrono::duration<double>(now - logged).count() >= period_;
  };
  std::lock_guard<std::mutex> lock(mutex_);
  const auto found = last_logged_.find(reason);
  if (found != last_logged_.end() && !expired(found->second)) return false;
  if (last_logged_.size() > kPruneAbove) {
    for (auto it = last_logged_.begin(); it != last_logged_.end();) {
      it = expired(it->second) ? last_logged_.erase(it) : std::next(it);
    }
  }
  last_logged_[reason] = now;
  return true;
}

void StageMonitor::publish(const ros::SteadyTimerEvent&) {
  diagnostic_msgs::DiagnosticStatus status;
  status.name = name_ + ": processing";
  status.hardware_id = "tabletop_shapes";
  setWarning("input", silentInputWarning());
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (window_skipped_ > 0) {
      status.level = diagnostic_msgs::DiagnosticStatus::WARN;
      status.message = "frames skipped: " + last_skip_reason_;
    } else if (window_without_result_ > 0) {
      status.level = diagnostic_msgs::DiagnosticStatus::WARN;
      status.message = "frames without result: " + last_no_result_reason_;
    } else if (window_frames_ == 0) {
      status.level = diagnostic_msgs::DiagnosticStatus::OK;
      status.message = "waiting for input";
    } else {
      status.level = diagnostic_msgs::DiagnosticStatus::OK;
      status.message = "ok";
    }
    const double mean_ms = window_frames_ > 0 ? window_sum_ms_ / window_frames_ : 0.0;
    status.values = {keyValue("frames", frames_),
                     keyValue("frames skipped", skipped_),
                     keyValue("frames skipped: chain busy", skipped_busy_),
                     keyValue("frames in last period", window_frames_),
                     keyValue("last frame [ms]", last_ms_),
                     keyValue("mean frame in last period [ms]", mean_ms),
                     keyValue("max frame in last period [ms]", window_max_ms_),
                     keyValue("points in (last frame)", last_points_in_),
                     keyValue("points out (last frame)", last_points_out_),
                     keyValue("input clouds shared (zero-copy)", inputs_shared_),
                     keyValue("input clouds copied", inputs_copied_),
                     keyValue("last skip reason", last_skip_reason_),
                     keyValue("frames without result", without_result_),
                     keyValue("last no-result reason", last_no_result_reason_),
                     keyValue("frames dropped at input queue", dropped_),
                     keyValue("process RSS [MB]", releaseMemoryAfterBurst(usual_rss_mb_))};
    // Standing warnings come first in the message: they say why the results may be wrong.
    std::string warnings;
    for (const auto& [key, warning] : warnings_) {
      warnings += (warnings.empty() ? "" : "; ") + warning.text;
      status.values.push_back(keyValue("warning: " + key, warning.text));
    }
    if (!warnings.empty()) {
      status.message =
          warnings +
          (status.level == diagnostic_msgs::DiagnosticStatus::OK ? "" : "; " + status.message);
      status.level = std::max<int8_t>(status.level, diagnostic_msgs::DiagnosticStatus::WARN);
    }
    window_frames_ = window_skipped_ = window_without_result_ = 0;
    window_sum_ms_ = window_max_ms_ = 0.0;
  }
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  array.status.push_back(status);
  publisher_.publish(array);
}

}  // namespace bridge
}  // namespace tabletop_shapes
