// The chain's entry point for point clouds: one subscription that takes a cloud by pointer when
// a nodelet in the same manager publishes pcl::PointCloud<pcl::PointXYZRGB> (our OpenNI2
// driver), and reads any other sensor_msgs/PointCloud2 (a bag, another process, another
// driver) after checking it, x y z only: the chain never uses colour, and a 16-byte point
// halves what a camera's 32-byte XYZRGB cloud costs to read and to preprocess. A plain
// subscription cannot do both: roscpp hands over the pointer only when the subscriber's type
// is the publisher's, and pcl_ros's reader accepts a cloud without x or with short data,
// warning per frame or reading garbage.
#pragma once

#include "tabletop_shapes/ros/cloud_pool.h"

#include <boost/shared_ptr.hpp>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <functional>
#include <string>

namespace tabletop_shapes {
namespace bridge {

// A cloud handed over by pointer (the driver's) and a PointCloud2 as it is read.
using InputCloud = pcl::PointCloud<pcl::PointXYZRGB>;
using ReceivedCloud = pcl::PointCloud<pcl::PointXYZ>;

// A serialised sensor_msgs/PointCloud2 read into `msg`, every length checked against the bytes
// present before anything is allocated (roscpp's deserializer resizes a vector to the length
// a message claims, so 20 bytes could ask for 4 GB). Empty on success, else what is wrong.
std::string deserializeCloud(const uint8_t* data, size_t size, sensor_msgs::PointCloud2& msg);

// Empty when `msg` can be read as little-endian x y z floats, else why not: sizes that do not
// add up (width x height x point_step, row_step, the data's length, exactly), more than
// `max_points` points, missing or non-float32 x y z. Checks the sizes before any loop over
// the data, so a refusal costs no more than the message's length.
std::string invalidCloudReason(const sensor_msgs::PointCloud2& msg, uint64_t max_points);

// x y z of a valid `msg`; layout and header kept. Reuses the memory `cloud` holds.
void readInputCloud(const sensor_msgs::PointCloud2& msg, ReceivedCloud& cloud);

// The same three steps without copying the point bytes into msg.data (a VGA XYZRGB cloud is
// ~10 MB, and the subscriber reads it straight from roscpp's receive buffer): `msg` gets every
// field but data, `points` / `point_bytes` locate the data inside `data`.
std::string deserializeCloudLayout(const uint8_t* data, size_t size, sensor_msgs::PointCloud2& msg,
                                   const uint8_t*& points, size_t& point_bytes);
std::string invalidCloudReason(const sensor_msgs::PointCloud2& layout, size_t point_bytes,
                               uint64_t max_points);
void readInputCloud(const sensor_msgs::PointCloud2& layout, const uint8_t* points,
                    ReceivedCloud& cloud);

// The header of a refused cloud (default-constructed when even it was unreadable), and why.
using InvalidCloudCallback = std::function<void(const std_msgs::Header&, const std::string&)>;

// Whether a valid cloud (its header) is taken in; false: the callback has answered it itself.
using AdmitCallback = std::function<bool(const std_msgs::Header&)>;

// Where the clouds `admit` takes in (all when `admit` is empty) go: `on_shared` gets a cloud
// handed over by pointer, `on_received` a PointCloud2 read (into one cloud reused from frame
// to frame while the callback does not keep it), `on_invalid` the reason a cloud was refused;
// all run on the node's callback queue. A PointCloud2 is admitted before its points are read
// (a refusal costs its header only). A cloud handed over by pointer is not checked here: its
// size against max_points is the caller's to check.
struct InputCloudCallbacks {
  std::function<void(const boost::shared_ptr<const InputCloud>&)> on_shared;
  std::function<void(const boost::shared_ptr<const ReceivedCloud>&)> on_received;
  InvalidCloudCallback on_invalid;
  AdmitCallback admit;
};
ros::Subscriber subscribeInputCloud(ros::NodeHandle& node, const std::string& topic,
                                    uint32_t queue_size, const InputCloudCallbacks& callbacks,
                                    uint64_t max_points);

}  // namespace bridge
}  // namespace tabletop_shapes
