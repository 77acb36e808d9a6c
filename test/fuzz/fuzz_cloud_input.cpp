// libFuzzer target: a serialised sensor_msgs/PointCloud2 as it arrives over TCP, through the
// same steps as the Preprocess nodelet's input (bounded deserialisation, the checks, the
// read into the chain's cloud).
#include "tabletop_shapes/ros/cloud_input.h"

#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace tabletop_shapes::bridge;
  sensor_msgs::PointCloud2 msg;
  if (!deserializeCloud(data, size, msg).empty()) return 0;
  if (!invalidCloudReason(msg, 1000000).empty()) return 0;
  InputCloud cloud;
  readInputCloud(msg, cloud);
  if (cloud.size() != static_cast<size_t>(msg.width) * msg.height) std::abort();
  return 0;
}
