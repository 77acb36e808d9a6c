// tf2 lookups at each frame's own stamp, for the stages that transform (TableSegmentation's
// ~up_frame, ShapeEstimation's ~output_frame): a bounded wait for a transform that comes after
// its cloud, and a buffer that follows the clouds when their stamps go back (a bag played with
// --loop, a recording restarted).
#pragma once

#include "tabletop_shapes/ros/stage_monitor.h"

#include <Eigen/Geometry>
#include <ros/ros.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <functional>
#include <memory>
#include <mutex>
#include <string>

namespace tabletop_shapes {
namespace bridge {

class FrameTransforms {
 public:
  // Called with a warning that names the jump when a frame's stamp is older than the last one.
  using JumpReport = std::function<void(const std::string& warning)>;

  // `timeout`: the longest wait for a transform that arrives after its frame. Fed by hand
  // (buffer().setTransform) until listen() is called.
  FrameTransforms(ros::Duration timeout, JumpReport report_jump);
  // Subscribes to /tf and /tf_static through `node`, on a thread of the listener's own (a wait
  // in lookup() does not hold up the transforms it waits for).
  void listen(ros::NodeHandle& node);
  tf2_ros::Buffer& buffer() { return buffer_; }

  // target <- source at `stamp`, the frame's own: a transform that moves between frames (a
  // camera on an arm) is taken at each frame's time, never a neighbour's. Waits at most the
  // timeout; throws tf2::TransformException naming what is missing. A stamp older than the
  // last one looked up is reported; more than the cache time (10 s) older, it first empties
  // the buffer's transforms (static ones stay): tf2 refuses transforms that much older than
  // its newest (TF_OLD_DATA), so after a long bag's loop every frame would lack its transform.
  Eigen::Isometry3d lookup(const std::string& target, const std::string& source,
                           const ros::Time& stamp);

 private:
  ros::Duration timeout_;
  JumpReport report_jump_;
  tf2_ros::Buffer buffer_;
  std::unique_ptr<tf2_ros::TransformListener> listener_;
  std::mutex mutex_;
  ros::Time last_stamp_;
};

// Reports each jump as a warning in the stage's log, throttled like its other problems.
FrameTransforms::JumpReport warnThrough(StageMonitor& monitor);

}  // namespace bridge
}  // namespace tabletop_shapes
