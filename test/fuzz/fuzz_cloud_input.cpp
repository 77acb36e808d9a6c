// libFuzzer target: a serialised sensor_msgs/PointCloud2 as it arrives over TCP, through the
// same steps as the Preprocess nodelet's input: the in-place path the subscriber uses (bounded
// layout deserialisation, the checks, the read straight from the receive buffer) and the
// copying path, which must refuse and read exactly the same.
#include "tabletop_shapes/ros/cloud_input.h"

#include <cstdlib>
#include <cstring>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace tabletop_shapes::bridge;
  constexpr uint64_t kMaxPoints = 1000000;

  sensor_msgs::PointCloud2 layout;
  const uint8_t* points = nullptr;
  size_t point_bytes = 0;
  const bool in_place_ok =
      deserializeCloudLayout(data, size, layout, points, point_bytes).empty() &&
      invalidCloudReason(layout, point_bytes, kMaxPoints).empty();

  sensor_msgs::PointCloud2 msg;
  const bool copied_ok =
      deserializeCloud(data, size, msg).empty() && invalidCloudReason(msg, kMaxPoints).empty();
  if (in_place_ok != copied_ok) std::abort();
  if (!copied_ok) return 0;

  ReceivedCloud cloud, in_place;
  readInputCloud(msg, cloud);
  readInputCloud(layout, points, in_place);
  if (cloud.size() != static_cast<size_t>(msg.width) * msg.height) std::abort();
  if (in_place.size() != cloud.size()) std::abort();
  // Bits, not floats: NaN payloads must compare equal too (the points' padding is not read).
  for (size_t i = 0; i < cloud.size(); ++i) {
    const pcl::PointXYZ &a = cloud.points[i], &b = in_place.points[i];
    if (std::memcmp(a.data, b.data, 3 * sizeof(float)) != 0) std::abort();
  }
  return 0;
}
