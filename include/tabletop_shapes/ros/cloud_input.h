// The chain's entry point for point clouds: one subscription that takes a cloud by pointer when
// a nodelet in the same manager publishes pcl::PointCloud<pcl::PointXYZRGB> (our OpenNI2
// driver), and reads any other sensor_msgs/PointCloud2 (a bag, another process, another
// driver) after checking it. A plain subscription cannot do both: roscpp hands over the
// pointer only when the subscriber's type is the publisher's, and pcl_ros's reader accepts a
// cloud without x or with short data, warning per frame or reading garbage.
#pragma once

#include <boost/shared_ptr.hpp>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <functional>
#include <string>

namespace tabletop_shapes {
namespace bridge {

using InputCloud = pcl::PointCloud<pcl::PointXYZRGB>;

// Empty when `msg` can be read as little-endian x y z floats, else why not.
std::string invalidCloudReason(const sensor_msgs::PointCloud2& msg);

// x y z (and rgb when the message has it) of a valid `msg`; layout and header kept.
void readInputCloud(const sensor_msgs::PointCloud2& msg, InputCloud& cloud);

// `on_cloud` gets every valid cloud, `on_invalid` the reason a cloud was refused; both run on
// the node's callback queue.
ros::Subscriber subscribeInputCloud(
    ros::NodeHandle& node, const std::string& topic, uint32_t queue_size,
    const std::function<void(const boost::shared_ptr<const InputCloud>&)>& on_cloud,
    const std::function<void(const std::string&)>& on_invalid);

}  // namespace bridge
}  // namespace tabletop_shapes
