#include "tabletop_shapes/core/playback_schedule.h"

#include <algorithm>

namespace tabletop_shapes {

void PlaybackSchedule::configure(int frame_period_us, double speed) {
  frame_period_us_ = std::max(1, frame_period_us);
  speed_ = speed > 0.0 ? speed : 1.0;
}

void PlaybackSchedule::reset() {
  const int period = frame_period_us_;
  const double speed = speed_;
  *this = PlaybackSchedule();
  configure(period, speed);
}

PlaybackSchedule::Clock::duration PlaybackSchedule::scaled(double microseconds) const {
  return std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double, std::micro>(microseconds / speed_));
}

PlaybackSchedule::Slot PlaybackSchedule::schedule(int stream, uint64_t device_us,
                                                  Clock::time_point now) {
  stream = std::clamp(stream, 0, kStreams - 1);
  const bool seen = stream_seen_[stream];
  const uint64_t previous_us = stream_last_us_[stream];
  stream_seen_[stream] = true;
  stream_last_us_[stream] = device_us;
  // A stream looped when its own device time stops advancing (a one-frame recording repeats
  // one stamp); the first stream to loop begins the next schedule, the other one joins it.
  if (seen && device_us <= previous_us) ++stream_loops_[stream];
  auto dueIn = [&](Clock::time_point origin, uint64_t origin_us) {
    return origin + scaled(static_cast<double>(device_us) - static_cast<double>(origin_us));
  };
  // The other stream's last frames of the previous loop: due as they were (no sleep).
  if (started_ && stream_loops_[stream] < loops_)
    return {dueIn(previous_origin_, previous_origin_us_), false};
  const bool jumped = seen && device_us > previous_us + 10ull * frame_period_us_;
  const bool restart = !started_ || stream_loops_[stream] > loops_ || jumped;
  if (restart) {
    previous_origin_ = origin_;
    previous_origin_us_ = origin_us_;
    loops_ = stream_loops_[stream];
    origin_ = started_ ? last_due_ + scaled(frame_period_us_) : now;
    // Far behind (the machine was too slow, or the driver paused): start again from now
    // rather than deliver a burst of overdue frames.
    if (origin_ < now - std::chrono::seconds(1)) origin_ = now;
    origin_us_ = device_us;
    started_ = true;
  }
  const Clock::time_point due = dueIn(origin_, origin_us_);
  last_due_ = restart ? due : std::max(last_due_, due);
  return {due, restart};
}

}  // namespace tabletop_shapes
