// When each frame of a looping recording is due (the OpenNI2 driver's playback pacing), kept
// free of ROS and OpenNI2 so that it is unit-tested with a clock of its own. OpenNI2's player
// (manual mode) delivers frames as fast as they are read and restarts a looping recording at
// once; the driver sleeps until each frame is due at the recorded rate times `speed`.
#pragma once

#include <chrono>
#include <cstdint>

namespace tabletop_shapes {

class PlaybackSchedule {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr int kStreams = 2;  // depth, colour

  struct Slot {
    Clock::time_point due;
    bool restarted;  // a new schedule began here (first frame, a loop, a jump in device time)
  };

  // frame_period_us: the recording's frame period; speed > 0 scales the recorded rate.
  void configure(int frame_period_us, double speed);
  // Forget the schedule (the streams were restarted).
  void reset();
  // The frame of `stream` (0 .. kStreams-1) recorded at device_us, delivered at `now`. A stream
  // whose device time does not advance has looped (a one-frame recording repeats one stamp):
  // the schedule continues one frame period after the last frame. Depth and colour of one
  // instant share their device time and so their due time. A jump forward by more than ten
  // frame periods begins a new schedule too; a schedule more than 1 s behind `now` restarts
  // from `now`.
  Slot schedule(int stream, uint64_t device_us, Clock::time_point now);

 private:
  Clock::duration scaled(double microseconds) const;

  int frame_period_us_ = 33333;
  double speed_ = 1.0;
  bool started_ = false;
  Clock::time_point origin_, last_due_, previous_origin_;
  uint64_t origin_us_ = 0, previous_origin_us_ = 0;
  uint64_t loops_ = 0;  // loops the schedule has followed
  uint64_t stream_loops_[kStreams] = {};
  uint64_t stream_last_us_[kStreams] = {};
  bool stream_seen_[kStreams] = {};
};

}  // namespace tabletop_shapes
