#include "tabletop_shapes/ros/frame_admission.h"

#include <algorithm>

namespace tabletop_shapes {
namespace bridge {

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

}  // namespace bridge
}  // namespace tabletop_shapes
