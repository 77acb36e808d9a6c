// Admission at the chain's entry (Preprocess): a frame is taken in only while fewer than a
// limit are between Preprocess and the chain's `objects` output. At 30 Hz the chain (~100 ms a
// frame on two cores) cannot take every frame; without a limit Preprocess worked on frames
// that a later queue then dropped unanswered, and the frames that did come through waited in
// queues beside them. A frame is done when an `objects` message with its stamp arrives (every
// stage that skips a frame publishes one too); a frame whose answer never comes (a stage died,
// a later queue lost it) is given up after a timeout, so that admission cannot stall.
// ROS-free (stamps in microseconds, a steady clock passed in) and thread-safe: the nodelet
// admits on its input queue and hears answers on another thread.
// In one manager an answer frees its frame's place before it is published (the registry
// below): heard only on the topic, it freed the place on a worker thread some time after a
// consumer in another process had it, and a frame that consumer sent at once was refused as
// busy (seen in CI: a frame sent after the last one's answer got "chain busy").
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

namespace tabletop_shapes {
namespace bridge {

// The `reason` of the objects message that answers a frame refused as busy:
// "skipped: chain busy (N frames in flight)"; consumers may match the prefix. Header-only, so
// that the tools that count answers (soak_monitor) need not link the nodelets.
constexpr const char* kChainBusyReason = "skipped: chain busy";
inline std::string chainBusyReason(size_t frames_in_flight) {
  return std::string(kChainBusyReason) + " (" + std::to_string(frames_in_flight) +
         (frames_in_flight == 1 ? " frame" : " frames") + " in flight)";
}
inline bool isChainBusyReason(const std::string& reason) {
  return reason.rfind(kChainBusyReason, 0) == 0;
}

class FrameAdmission {
 public:
  using Clock = std::chrono::steady_clock;

  // `max_in_flight`: frames admitted and not yet answered; 0 admits every frame and tracks
  // none (the chain without admission: later queues drop what they cannot take).
  // `timeout_seconds`: a frame unanswered that long no longer counts as in flight.
  FrameAdmission(size_t max_in_flight, double timeout_seconds);

  void setLimits(size_t max_in_flight, double timeout_seconds);

  struct Decision {
    bool admitted = false;
    size_t in_flight = 0;  // frames in flight when the frame came (before admitting it)
    // Stamps of frames given up on (timed out) by this call, oldest first.
    std::vector<uint64_t> timed_out_stamps_us;
  };
  // A frame stamped `stamp_us` arrives at `now`: frames unanswered for longer than the timeout
  // are given up first, then it is admitted while fewer than the limit are in flight.
  Decision admit(uint64_t stamp_us, Clock::time_point now);

  // An `objects` message stamped `stamp_us` heard on the topic: the oldest frame in flight
  // with that stamp is done. False (nothing changes) when no frame in flight has it: an answer
  // to a frame never admitted (refused as busy or invalid), one already given up on, or one
  // already counted by answeredInProcess. Stamps need not increase: a looped bag's stamps go
  // back, and a publisher may repeat a stamp.
  bool answered(uint64_t stamp_us);
  // The same answer, told by a stage of this process just before it publishes it: the frame
  // is done at once, and the answer heard on the topic later frees nothing more.
  bool answeredInProcess(uint64_t stamp_us);

  size_t inFlight() const;

  // A ros::Time's stamp as the later stages carry it (their PCL headers hold whole
  // microseconds), so that the input's stamp and the answer's match.
  static uint64_t stampMicroseconds(uint64_t stamp_nanoseconds) { return stamp_nanoseconds / 1000; }

 private:
  struct Frame {
    uint64_t stamp_us;
    Clock::time_point admitted;
  };
  mutable std::mutex mutex_;
  size_t max_in_flight_;
  Clock::duration timeout_;
  std::deque<Frame> in_flight_;  // in the order admitted
  // Stamps answered in process whose topic copy has not been heard yet (bounded: a copy lost
  // at the subscriber's queue must not make this grow).
  std::deque<uint64_t> heard_in_process_;
  bool removeInFlight(uint64_t stamp_us);
};

// The admissions of this process by the resolved name of the topic their answers come on
// (Preprocess's `objects`), so that a stage publishing an answer there frees the frame's
// place first (publishAnswer in ros/answer_publisher.h). Thread-safe; an admission is
// removed before it is destroyed.
void registerAdmission(const std::string& answer_topic, FrameAdmission* admission);
void unregisterAdmission(const std::string& answer_topic, const FrameAdmission* admission);
// Frees the place of the frame stamped `stamp_us` in every admission answered on the topic.
void frameAnsweredInProcess(const std::string& answer_topic, uint64_t stamp_us);

}  // namespace bridge
}  // namespace tabletop_shapes
