#include "tabletop_shapes/ros/frame_transforms.h"

#include <cstdio>
#include <utility>

namespace tabletop_shapes {
namespace bridge {

FrameTransforms::FrameTransforms(ros::Duration timeout, JumpReport report_jump)
    : timeout_(timeout), report_jump_(std::move(report_jump)) {}

void FrameTransforms::listen(ros::NodeHandle& node) {
  listener_ = std::make_unique<tf2_ros::TransformListener>(buffer_, node);
}

Eigen::Isometry3d FrameTransforms::lookup(const std::string& target, const std::string& source,
                                          const ros::Time& stamp) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stamp < last_stamp_) {
      // Within the cache time tf2 still takes the transforms of the older stamps: keep them.
      const bool beyond_cache = last_stamp_ - stamp > buffer_.getCacheLength();
      if (beyond_cache) buffer_.clear();
      char text[320];
      std::snprintf(text, sizeof(text),
                    "frame stamps went back %.3f s (from %.3f to %.3f; a bag played in a loop?)%s",
                    (last_stamp_ - stamp).toSec(), last_stamp_.toSec(), stamp.toSec(),
                    beyond_cache ? ": more than tf's cache time, transforms received before "
                                   "dropped (static ones kept)"
                                 : "");
      if (report_jump_) report_jump_(text);
    }
    last_stamp_ = stamp;
  }
  const geometry_msgs::TransformStamped transform =
      buffer_.lookupTransform(target, source, stamp, timeout_);
  const auto& t = transform.transform.translation;
  const auto& q = transform.transform.rotation;
  Eigen::Isometry3d target_from_source = Eigen::Isometry3d::Identity();
  target_from_source.translation() = Eigen::Vector3d(t.x, t.y, t.z);
  target_from_source.linear() =
      Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
  return target_from_source;
}

FrameTransforms::JumpReport warnThrough(StageMonitor& monitor) {
  return [&monitor](const std::string& warning) {
    monitor.log({Problem::Level::Warn, warning, "frame stamps went back"});
  };
}

}  // namespace bridge
}  // namespace tabletop_shapes
