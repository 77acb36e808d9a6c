#include "tabletop_shapes/ros/frame_admission.h"

#include <algorithm>
#include <map>

namespace tabletop_shapes {
namespace bridge {
namespace {

// Answers counted in process whose topic copy is awaited: a few frame periods' worth.
constexpr size_t kHeardInProcessKept = 64;

std::mutex registry_mutex;
std::multimap<std::string, FrameAdmission*>& registry() {
  static std::multimap<std::string, FrameAdmission*> admissions;
  return admissions;
}

}  // namespace

FrameAdmission::FrameAdmission(size_t max_in_flight, double timeout_seconds) {
  setLimits(max_in_flight, timeout_seconds);
}

void FrameAdmission::setLimits(size_t max_in_flight, double timeout_seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  max_in_flight_ = max_in_flight;
  timeout_ = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(std::max(0.0, timeout_seconds)));
}

FrameAdmission::Decision FrameAdmission::admit(uint64_t stamp_us, Clock::time_point now) {
  std::lock_guard<std::mutex> lock(mutex_);
  Decision decision;
  // Admitted in time order: the timed-out frames are at the front.
  while (!in_flight_.empty() && now - in_flight_.front().admitted > timeout_) {
    decision.timed_out_stamps_us.push_back(in_flight_.front().stamp_us);
    in_flight_.pop_front();
  }
  decision.in_flight = in_flight_.size();
  // Without a limit nothing is tracked: later queues may drop frames then, and a frame
  // dropped there is no stage's fault to warn about.
  if (max_in_flight_ == 0) {
    decision.admitted = true;
    return decision;
  }
  decision.admitted = in_flight_.size() < max_in_flight_;
  if (decision.admitted) in_flight_.push_back({stamp_us, now});
  return decision;
}

bool FrameAdmission::answered(uint64_t stamp_us) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto heard = std::find(heard_in_process_.begin(), heard_in_process_.end(), stamp_us);
  if (heard != heard_in_process_.end()) {
    heard_in_process_.erase(heard);
    return false;
  }
  return removeInFlight(stamp_us);
}

bool FrameAdmission::answeredInProcess(uint64_t stamp_us) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!removeInFlight(stamp_us)) return false;
  heard_in_process_.push_back(stamp_us);
  if (heard_in_process_.size() > kHeardInProcessKept) heard_in_process_.pop_front();
  return true;
}

bool FrameAdmission::removeInFlight(uint64_t stamp_us) {
  const auto found = std::find_if(in_flight_.begin(), in_flight_.end(),
                                  [&](const Frame& frame) { return frame.stamp_us == stamp_us; });
  if (found == in_flight_.end()) return false;
  in_flight_.erase(found);
  return true;
}

size_t FrameAdmission::inFlight() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return in_flight_.size();
}

void registerAdmission(const std::string& answer_topic, FrameAdmission* admission) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  registry().emplace(answer_topic, admission);
}

void unregisterAdmission(const std::string& answer_topic, const FrameAdmission* admission) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  const auto range = registry().equal_range(answer_topic);
  for (auto it = range.first; it != range.second; ++it) {
    if (it->second == admission) {
      registry().erase(it);
      return;
    }
  }
}

void frameAnsweredInProcess(const std::string& answer_topic, uint64_t stamp_us) {
  std::lock_guard<std::mutex> lock(registry_mutex);
  const auto range = registry().equal_range(answer_topic);
  for (auto it = range.first; it != range.second; ++it) it->second->answeredInProcess(stamp_us);
}

}  // namespace bridge
}  // namespace tabletop_shapes
