// A ROS message through ROS serialisation and back: what a subscriber in another process (or a
// bag) receives.
#pragma once

#include <ros/serialization.h>

#include <cstdint>
#include <vector>

namespace tabletop_shapes_test {

template <typename Msg>
Msg roundTrip(const Msg& in) {
  const uint32_t size = ros::serialization::serializationLength(in);
  std::vector<uint8_t> buffer(size);
  ros::serialization::OStream out_stream(buffer.data(), size);
  ros::serialization::serialize(out_stream, in);
  Msg out;
  ros::serialization::IStream in_stream(buffer.data(), size);
  ros::serialization::deserialize(in_stream, out);
  return out;
}

}  // namespace tabletop_shapes_test
