// PointCloud2 -> the chain's input cloud, without a master: every malformed size is refused
// with its reason before any loop over the data (issue 16, findings 3 and 4), and a valid
// cloud is read exactly.
#include "tabletop_shapes/ros/cloud_input.h"

#include "tabletop_shapes/core/parallel.h"

#include <gtest/gtest.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <chrono>
#include <cstring>
#include <limits>
#include <string>

namespace tabletop_shapes {
namespace {

using bridge::invalidCloudReason;
constexpr uint64_t kCap = 4000000;

sensor_msgs::PointCloud2 xyzCloud(uint32_t width, uint32_t height) {
  sensor_msgs::PointCloud2 cloud;
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2FieldsByString(1, "xyz");  // point_step 16
  modifier.resize(static_cast<size_t>(width) * height);
  cloud.width = width;
  cloud.height = height;
  cloud.row_step = width * cloud.point_step;
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
  for (uint32_t i = 0; i < width * height; ++i, ++x, ++y, ++z) {
    *x = 0.01f * i;
    *y = -0.5f;
    *z = 1.0f + 0.001f * i;
  }
  return cloud;
}

TEST(CloudInput, ValidCloudIsReadExactly) {
  sensor_msgs::PointCloud2 msg = xyzCloud(4, 3);
  msg.header.frame_id = "camera";
  msg.header.seq = 42;
  ASSERT_EQ(invalidCloudReason(msg, kCap), "");
  bridge::ReceivedCloud cloud;
  bridge::readInputCloud(msg, cloud);
  ASSERT_EQ(cloud.size(), 12u);
  EXPECT_EQ(cloud.width, 4u);
  EXPECT_EQ(cloud.height, 3u);
  EXPECT_EQ(cloud.header.seq, 42u);
  EXPECT_EQ(cloud.header.frame_id, "camera");
  EXPECT_FLOAT_EQ(cloud.points[11].x, 0.11f);
  EXPECT_FLOAT_EQ(cloud.points[11].z, 1.011f);
  EXPECT_EQ(invalidCloudReason(xyzCloud(0, 1), kCap), "") << "the empty cloud";
  EXPECT_EQ(invalidCloudReason(xyzCloud(0, 0), kCap), "");
}

// A camera's XYZRGB cloud (depth_image_proc's layout: x y z at 0 4 8, rgb at 16, 32 bytes a
// point) is read as x y z; a reused cloud holding a larger frame keeps nothing of it.
TEST(CloudInput, ColourCloudIsReadAsXyzIntoAReusedCloud) {
  sensor_msgs::PointCloud2 msg;
  sensor_msgs::PointCloud2Modifier modifier(msg);
  modifier.setPointCloud2FieldsByString(2, "xyz", "rgb");
  ASSERT_EQ(msg.point_step, 32u);
  modifier.resize(6);
  msg.width = 3;
  msg.height = 2;
  msg.row_step = 3 * msg.point_step;
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x"), y(msg, "y"), z(msg, "z");
  sensor_msgs::PointCloud2Iterator<uint8_t> rgb(msg, "rgb");
  for (int i = 0; i < 6; ++i, ++x, ++y, ++z, ++rgb) {
    *x = 0.5f * i;
    *y = -0.25f * i;
    *z = 2.0f + i;
    rgb[0] = rgb[1] = rgb[2] = 200;
  }
  ASSERT_EQ(invalidCloudReason(msg, kCap), "");
  bridge::ReceivedCloud cloud;
  cloud.points.assign(10, pcl::PointXYZ(9.0f, 9.0f, 9.0f));
  cloud.points[4].data[3] = 7.0f;
  bridge::readInputCloud(msg, cloud);
  ASSERT_EQ(cloud.size(), 6u);
  EXPECT_EQ(cloud.width, 3u);
  EXPECT_EQ(cloud.height, 2u);
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(cloud.points[i].x, 0.5f * i) << i;
    EXPECT_EQ(cloud.points[i].y, -0.25f * i) << i;
    EXPECT_EQ(cloud.points[i].z, 2.0f + i) << i;
    EXPECT_EQ(cloud.points[i].data[3], 1.0f) << i << ": as a constructed point's";
  }
}

// A camera-sized cloud is read in bands of points on two threads: bands that start inside a
// row, rows that end in padding (row_step beyond width x point_step) and x y z at other
// offsets than 0 4 8 all land on the right points; so do x y z at 0 4 8 (each point one 16-byte
// load) and packed 12-byte points.
size_t wronglyReadPoints(uint32_t offset_x, uint32_t offset_y, uint32_t offset_z,
                         uint32_t point_step) {
  constexpr uint32_t kWidth = 641, kHeight = 77, kRowPadding = 12;
  sensor_msgs::PointCloud2 msg;
  msg.width = kWidth;
  msg.height = kHeight;
  msg.point_step = point_step;
  msg.row_step = kWidth * point_step + kRowPadding;
  const uint32_t offsets[3] = {offset_x, offset_y, offset_z};
  for (const auto& [name, offset] :
       {std::pair<const char*, uint32_t>{"z", offset_z}, {"x", offset_x}, {"y", offset_y}}) {
    sensor_msgs::PointField field;
    field.name = name;
    field.offset = offset;
    field.datatype = sensor_msgs::PointField::FLOAT32;
    field.count = 1;
    msg.fields.push_back(field);
  }
  msg.data.assign(static_cast<size_t>(msg.row_step) * kHeight, 0xff);  // padding: NaN bytes
  const auto valueAt = [](uint32_t row, uint32_t column, int axis) {
    return static_cast<float>(row) + 0.001f * static_cast<float>(column) + 1000.0f * axis;
  };
  for (uint32_t row = 0; row < kHeight; ++row) {
    for (uint32_t column = 0; column < kWidth; ++column) {
      uint8_t* point = msg.data.data() + row * msg.row_step + column * point_step;
      for (int axis = 0; axis < 3; ++axis) {
        const float value = valueAt(row, column, axis);
        std::memcpy(point + offsets[axis], &value, 4);
      }
    }
  }
  const std::string invalid = invalidCloudReason(msg, kCap);
  EXPECT_EQ(invalid, "");
  if (!invalid.empty()) return msg.width * msg.height;  // not read: the reader trusts the check
  setWorkerThreads(2);
  bridge::ReceivedCloud cloud;
  bridge::readInputCloud(msg, cloud);
  setWorkerThreads(0);
  EXPECT_EQ(cloud.size(), static_cast<size_t>(kWidth) * kHeight);
  if (cloud.size() != static_cast<size_t>(kWidth) * kHeight) return cloud.size();
  size_t wrong = 0;
  for (uint32_t row = 0; row < kHeight; ++row) {
    for (uint32_t column = 0; column < kWidth; ++column) {
      const pcl::PointXYZ& p = cloud.points[row * kWidth + column];
      wrong += p.x != valueAt(row, column, 0) || p.y != valueAt(row, column, 1) ||
               p.z != valueAt(row, column, 2) || p.data[3] != 1.0f;
    }
  }
  return wrong;
}

TEST(CloudInput, LargeCloudIsReadInBandsOnTwoThreads) {
  EXPECT_EQ(wronglyReadPoints(8, 12, 4, 20), 0u);
  EXPECT_EQ(wronglyReadPoints(0, 4, 8, 20), 0u);
  EXPECT_EQ(wronglyReadPoints(0, 4, 8, 12), 0u);
}

// The cloud of the last frame is read into again once nobody holds it; one still held, or one
// far larger than the frame (after a burst), is not.
TEST(CloudInput, ReceivedCloudIsReusedOnceReleased) {
  bridge::CloudPool<pcl::PointXYZ> pool;
  boost::shared_ptr<bridge::ReceivedCloud> first = pool.next(1000);
  first->points.resize(1000);
  boost::shared_ptr<bridge::ReceivedCloud> second = pool.next(1000);
  EXPECT_NE(second.get(), first.get()) << "the first frame is still held: a new cloud";
  second->points.resize(1000);
  const bridge::ReceivedCloud* second_address = second.get();
  first.reset();
  second.reset();
  boost::shared_ptr<bridge::ReceivedCloud> third = pool.next(900);
  EXPECT_EQ(third.get(), second_address) << "released: read into again";
  EXPECT_EQ(third->points.capacity(), 1000u);
  third.reset();
  EXPECT_NE(pool.next(400).get(), second_address) << "over twice the frame's points: not kept";
}

// Finding 3: 108 bytes with width 0, height 2^32-1 and row_step 0 stalled the chain 5-12 s.
TEST(CloudInput, EmptyCloudWithBillionsOfRowsIsRefusedAtOnce) {
  sensor_msgs::PointCloud2 msg = xyzCloud(0, 1);
  msg.height = std::numeric_limits<uint32_t>::max();
  msg.row_step = 0;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(invalidCloudReason(msg, kCap),
            "width 0 x height 4294967295: an empty cloud is 0 x 0, 0 x 1 or 1 x 0");
  // The stall was 5-12 s; 1 s catches it without failing when a loaded machine deschedules us.
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
}

// Finding 4: 100 x 100 declared, 4.9 MB carried, read without comment.
TEST(CloudInput, DataLongerOrShorterThanDeclaredIsRefused) {
  sensor_msgs::PointCloud2 longer = xyzCloud(100, 100);
  longer.data.resize(4900000);
  EXPECT_EQ(invalidCloudReason(longer, kCap),
            "data longer than declared: 4900000 bytes, row_step 1600 x height 100 = 160000");
  sensor_msgs::PointCloud2 shorter = xyzCloud(100, 100);
  shorter.data.resize(100);
  EXPECT_EQ(invalidCloudReason(shorter, kCap),
            "data shorter than declared: 100 bytes, row_step 1600 x height 100 = 160000");
}

TEST(CloudInput, MalformedStepsAreRefused) {
  sensor_msgs::PointCloud2 row = xyzCloud(10, 10);
  row.row_step = 10;
  EXPECT_EQ(invalidCloudReason(row, kCap), "row_step 10 is shorter than width 10 x point_step 16");
  sensor_msgs::PointCloud2 point = xyzCloud(10, 10);
  point.point_step = 4;
  EXPECT_EQ(invalidCloudReason(point, kCap), "field 'y' at offset 4 overflows point_step 4");
  sensor_msgs::PointCloud2 zero = xyzCloud(10, 10);
  zero.point_step = 0;
  zero.row_step = 0;
  EXPECT_EQ(invalidCloudReason(zero, kCap), "field 'x' at offset 0 overflows point_step 0");
  sensor_msgs::PointCloud2 overflow = xyzCloud(10, 10);  // row_step x height past 2^32
  overflow.row_step = 0x80000000u;
  EXPECT_EQ(invalidCloudReason(overflow, kCap),
            "data shorter than declared: 1600 bytes, row_step 2147483648 x height 10 = "
            "21474836480");
}

TEST(CloudInput, FieldsAreChecked) {
  sensor_msgs::PointCloud2 no_z = xyzCloud(2, 1);
  no_z.fields.pop_back();
  EXPECT_EQ(invalidCloudReason(no_z, kCap), "no field 'z'");
  sensor_msgs::PointCloud2 float64 = xyzCloud(2, 1);
  float64.fields[1].datatype = sensor_msgs::PointField::FLOAT64;
  EXPECT_EQ(invalidCloudReason(float64, kCap), "field 'y' is not FLOAT32");
  sensor_msgs::PointCloud2 big_endian = xyzCloud(2, 1);
  big_endian.is_bigendian = true;
  EXPECT_EQ(invalidCloudReason(big_endian, kCap), "big-endian data");
}

// 5 million points: refused from the sizes alone, before a point is read.
TEST(CloudInput, PointsAboveTheCapAreRefused) {
  sensor_msgs::PointCloud2 msg = xyzCloud(0, 1);
  msg.width = 2500;
  msg.height = 2000;
  EXPECT_EQ(invalidCloudReason(msg, kCap),
            "5000000 points (2500 x 2000) is above max_points 4000000");
  EXPECT_EQ(invalidCloudReason(xyzCloud(30, 20), 599),
            "600 points (30 x 20) is above max_points 599");
  EXPECT_EQ(invalidCloudReason(xyzCloud(30, 20), 600), "");
}

std::vector<uint8_t> serialize(const sensor_msgs::PointCloud2& msg) {
  std::vector<uint8_t> bytes(ros::serialization::serializationLength(msg));
  ros::serialization::OStream stream(bytes.data(), bytes.size());
  ros::serialization::serialize(stream, msg);
  return bytes;
}

TEST(CloudInput, DeserializesWhatRoscppSerializes) {
  sensor_msgs::PointCloud2 msg = xyzCloud(5, 2);
  msg.header.frame_id = "camera";
  msg.header.stamp = ros::Time(12, 345);
  const std::vector<uint8_t> bytes = serialize(msg);
  sensor_msgs::PointCloud2 read;
  ASSERT_EQ(bridge::deserializeCloud(bytes.data(), bytes.size(), read), "");
  EXPECT_EQ(serialize(read), bytes);
  EXPECT_EQ(read.header.stamp, ros::Time(12, 345));
  EXPECT_EQ(read.fields.size(), 3u);
}

// The subscriber's path: the points are read where roscpp received them, with the same
// checks and the same cloud as through a PointCloud2 copy.
TEST(CloudInput, PointsAreReadInPlaceFromTheReceivedBytes) {
  sensor_msgs::PointCloud2 msg = xyzCloud(6, 4);
  msg.header.frame_id = "camera";
  const std::vector<uint8_t> bytes = serialize(msg);
  sensor_msgs::PointCloud2 layout;
  const uint8_t* points = nullptr;
  size_t point_bytes = 0;
  ASSERT_EQ(bridge::deserializeCloudLayout(bytes.data(), bytes.size(), layout, points, point_bytes),
            "");
  EXPECT_TRUE(layout.data.empty());
  EXPECT_EQ(point_bytes, 6u * 4u * 16u);
  // The data ends one byte (is_dense) before the message.
  EXPECT_EQ(points + point_bytes, bytes.data() + bytes.size() - 1);
  ASSERT_EQ(invalidCloudReason(layout, point_bytes, kCap), "");
  EXPECT_EQ(invalidCloudReason(layout, point_bytes - 16, kCap),
            "data shorter than declared: 368 bytes, row_step 96 x height 4 = 384");
  bridge::ReceivedCloud in_place, copied;
  bridge::readInputCloud(layout, points, in_place);
  bridge::readInputCloud(msg, copied);
  ASSERT_EQ(in_place.size(), 24u);
  EXPECT_EQ(in_place.header.frame_id, "camera");
  for (size_t i = 0; i < in_place.size(); ++i) {
    EXPECT_EQ(in_place.points[i].getVector3fMap(), copied.points[i].getVector3fMap()) << i;
  }
  EXPECT_FLOAT_EQ(in_place.points[23].z, 1.023f);
}

// roscpp's own deserializer resizes to the claimed length before it checks the bytes: a few
// bytes claiming 4 GB of data are refused here without allocating.
TEST(CloudInput, ClaimedLengthsBeyondTheMessageAreRefused) {
  const sensor_msgs::PointCloud2 msg = xyzCloud(5, 2);
  std::vector<uint8_t> bytes = serialize(msg);
  sensor_msgs::PointCloud2 read;
  const size_t data_length_at = bytes.size() - 1 - msg.data.size() - 4;
  std::memset(&bytes[data_length_at], 0xff, 4);
  EXPECT_EQ(bridge::deserializeCloud(bytes.data(), bytes.size(), read),
            "data cut short (its length exceeds the message)");
  std::vector<uint8_t> fields = serialize(msg);
  std::memset(&fields[4 + 8 + 4 + 8], 0xff, 4);  // after seq, stamp, frame_id "", height, width
  EXPECT_EQ(bridge::deserializeCloud(fields.data(), fields.size(), read), "header cut short");
  std::vector<uint8_t> longer = serialize(msg);
  longer.push_back(0);
  EXPECT_EQ(bridge::deserializeCloud(longer.data(), longer.size(), read),
            "1 bytes after the cloud");
  for (size_t cut = 0; cut < bytes.size(); cut += 7) {
    const std::vector<uint8_t> whole = serialize(msg);
    EXPECT_NE(bridge::deserializeCloud(whole.data(), cut, read), "") << cut;
  }
}

}  // namespace
}  // namespace tabletop_shapes
