// See include/tabletop_shapes/ros/cloud_input.h.
#include "tabletop_shapes/ros/cloud_input.h"

#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <ros/subscription_callback_helper.h>

#include <algorithm>
#include <cstring>

namespace tabletop_shapes {
namespace bridge {

namespace {

const sensor_msgs::PointField* findField(const sensor_msgs::PointCloud2& msg, const char* name) {
  const auto field = std::find_if(msg.fields.begin(), msg.fields.end(),
                                  [&](const sensor_msgs::PointField& f) { return f.name == name; });
  return field == msg.fields.end() ? nullptr : &*field;
}

using CloudCallbackParameter = const boost::shared_ptr<const InputCloud>&;

// roscpp calls deserialize() only for a message that did not arrive as an InputCloud object
// (the pointer path skips it), on the subscriber's callback queue; a null result drops the
// message before the callback.
class InputCloudHelper : public ros::SubscriptionCallbackHelperT<CloudCallbackParameter> {
 public:
  InputCloudHelper(const std::function<void(CloudCallbackParameter)>& on_cloud,
                   const std::function<void(const std::string&)>& on_invalid)
      : ros::SubscriptionCallbackHelperT<CloudCallbackParameter>(on_cloud),
        on_invalid_(on_invalid) {}

  ros::VoidConstPtr deserialize(
      const ros::SubscriptionCallbackHelperDeserializeParams& params) override {
    sensor_msgs::PointCloud2 msg;
    try {
      ros::serialization::IStream stream(params.buffer, params.length);
      ros::serialization::deserialize(stream, msg);
    } catch (const ros::Exception& e) {
      on_invalid_(std::string("unreadable message: ") + e.what());
      return {};
    }
    const std::string invalid = invalidCloudReason(msg);
    if (!invalid.empty()) {
      on_invalid_(invalid);
      return {};
    }
    auto cloud = boost::make_shared<InputCloud>();
    readInputCloud(msg, *cloud);
    return cloud;
  }

 private:
  std::function<void(const std::string&)> on_invalid_;
};

}  // namespace

std::string invalidCloudReason(const sensor_msgs::PointCloud2& msg) {
  if (msg.is_bigendian) return "big-endian data";
  for (const char* axis : {"x", "y", "z"}) {
    const sensor_msgs::PointField* field = findField(msg, axis);
    if (!field) return std::string("no field '") + axis + "'";
    if (field->datatype != sensor_msgs::PointField::FLOAT32) {
      return std::string("field '") + axis + "' is not FLOAT32";
    }
    if (field->offset + 4 > msg.point_step) return std::string("field '") + axis + "' overflows";
  }
  if (static_cast<uint64_t>(msg.row_step) * msg.height > msg.data.size() ||
      static_cast<uint64_t>(msg.point_step) * msg.width > msg.row_step) {
    return "data shorter than width x height x point_step";
  }
  return "";
}

void readInputCloud(const sensor_msgs::PointCloud2& msg, InputCloud& cloud) {
  cloud.header = pcl_conversions::toPCL(msg.header);
  cloud.width = msg.width;
  cloud.height = msg.height;
  cloud.is_dense = msg.is_dense;
  cloud.points.resize(static_cast<size_t>(msg.width) * msg.height);
  const uint32_t offset_x = findField(msg, "x")->offset, offset_y = findField(msg, "y")->offset,
                 offset_z = findField(msg, "z")->offset;
  // Colour is optional and 4 bytes wide as "rgb" (float or uint32) or "rgba".
  const sensor_msgs::PointField* rgb = findField(msg, "rgb");
  if (!rgb) rgb = findField(msg, "rgba");
  if (rgb && rgb->offset + 4 > msg.point_step) rgb = nullptr;
  size_t i = 0;
  for (uint32_t row = 0; row < msg.height; ++row) {
    const uint8_t* point = msg.data.data() + static_cast<size_t>(row) * msg.row_step;
    for (uint32_t column = 0; column < msg.width; ++column, ++i, point += msg.point_step) {
      pcl::PointXYZRGB& p = cloud.points[i];
      std::memcpy(&p.x, point + offset_x, 4);
      std::memcpy(&p.y, point + offset_y, 4);
      std::memcpy(&p.z, point + offset_z, 4);
      p.rgba = 0;
      if (rgb) std::memcpy(&p.rgba, point + rgb->offset, 4);
    }
  }
}

ros::Subscriber subscribeInputCloud(
    ros::NodeHandle& node, const std::string& topic, uint32_t queue_size,
    const std::function<void(const boost::shared_ptr<const InputCloud>&)>& on_cloud,
    const std::function<void(const std::string&)>& on_invalid) {
  ros::SubscribeOptions options;
  // Topic type and checksum are PointCloud2's (pcl_ros's traits); the helper does the rest.
  options.init<InputCloud>(topic, queue_size, on_cloud);
  options.helper = boost::make_shared<InputCloudHelper>(on_cloud, on_invalid);
  return node.subscribe(options);
}

}  // namespace bridge
}  // namespace tabletop_shapes
