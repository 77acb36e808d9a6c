#include "tabletop_shapes/core/camera_session.h"

#include "tabletop_shapes/core/oni_recording.h"

#include <algorithm>
#include <cstdio>
#include <utility>

namespace tabletop_shapes {

CameraSession::CameraSession(CameraBackend& backend, CameraSessionOptions options, CameraLog log,
                             Now now)
    : backend_(backend), options_(std::move(options)), log_(std::move(log)), now_(std::move(now)) {}

void CameraSession::report(const std::string& problem, const std::string& detail) {
  // Throttled: a new problem at once, the same one again every problem_report_interval.
  const Clock::time_point now = now_();
  if (problem != last_problem_ ||
      now - last_problem_time_ > std::chrono::duration<double>(options_.problem_report_interval)) {
    log_(CameraLogLevel::kError, problem + detail);
    last_problem_ = problem;
    last_problem_time_ = now;
  }
}

bool CameraSession::open() {
  std::string problem;
  // OpenNI2's file driver refuses a damaged recording without saying why, or plays it until
  // it crashes: check it ourselves first.
  if (looksLikeRecording(options_.device_id)) problem = oniRecordingProblem(options_.device_id);
  if (problem.empty()) device_ = backend_.open(options_.device_id, &problem);
  if (!device_) {
    if (problem.empty()) problem = "cannot open device '" + options_.device_id + "'";
    char retry[64];
    std::snprintf(retry, sizeof(retry), "; retrying in %.1f s", backoff_);
    report(problem, retry);
    return false;
  }
  log_(CameraLogLevel::kInfo, "opened " + device_->description());
  if (!last_problem_.empty()) log_(CameraLogLevel::kInfo, "the device is back");
  last_problem_.clear();
  backoff_ = 0.5;
  started_depth_ = started_color_ = false;
  return true;
}

CameraSession::Step CameraSession::step(bool want_depth, bool want_color, bool restart, int wait_ms,
                                        CameraFrame* frame) {
  Step result;
  if (!device_ && !open()) {
    result.kind = Step::kRetry;
    result.wait_seconds = backoff_;
    backoff_ = std::min(backoff_ * 2.0, options_.reconnect_max_interval);
    return result;
  }
  // Restart the streams when the wanted set changes (or a mode did), not when a sensor the
  // device lacks is wanted: a device without colour gives XYZ clouds.
  if (restart || want_depth != started_depth_ || want_color != started_color_) {
    const bool was_idle = !started_depth_ && !started_color_;
    device_->stopStreams();
    started_depth_ = want_depth;
    started_color_ = want_color;
    if (want_depth || want_color) {
      device_->startStreams(want_depth, want_color, log_);
      result.streams_started = true;
      last_frame_ = now_();
      if (was_idle) log_(CameraLogLevel::kInfo, "streaming (someone subscribed)");
    } else {
      log_(CameraLogLevel::kInfo, "no subscribers; streams stopped");
    }
  }
  if (!started_depth_ && !started_color_) {
    result.kind = Step::kIdle;
    result.wait_seconds = 0.1;
    return result;
  }
  if (device_->waitForFrame(wait_ms, frame)) {
    last_frame_ = now_();
    result.kind = Step::kFrame;
    return result;
  }
  result.kind = Step::kNoFrame;
  const double silent = std::chrono::duration<double>(now_() - last_frame_).count();
  if (silent > options_.frame_timeout) {
    char seconds[32];
    std::snprintf(seconds, sizeof(seconds), "%.1f", silent);
    report("no frames from '" + options_.device_id + "' for " + seconds +
           " s: the camera was unplugged or stalled; reopening it");
    close();
  }
  return result;
}

void CameraSession::close() {
  if (!device_) return;
  device_->stopStreams();
  device_.reset();
  started_depth_ = started_color_ = false;
}

}  // namespace tabletop_shapes
