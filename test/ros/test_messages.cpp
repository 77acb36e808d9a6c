// Round trips of the package's messages through ROS serialisation: what a subscriber in
// another process (or a bag) receives equals what was published.
#include <gtest/gtest.h>

#include "message_round_trip.h"

#include <shape_msgs/SolidPrimitive.h>
#include <tabletop_shapes/Objects.h>

#include <vector>

namespace {

using tabletop_shapes_test::roundTrip;

tabletop_shapes::Objects makeObjects() {
  tabletop_shapes::Objects msg;
  msg.header.frame_id = "camera_rgb_optical_frame";
  msg.header.stamp = ros::Time(1700000000, 123456000);
  msg.header.seq = 7;
  msg.table_found = true;
  msg.table.header = msg.header;
  msg.table.coefficients = {0.0, -0.8, -0.6, 0.9};
  for (int i = 0; i < 4; ++i) {
    geometry_msgs::Point32 p;
    p.x = 0.1f * i;
    p.y = 0.2f;
    p.z = 1.0f + 0.05f * i;
    msg.table.hull.points.push_back(p);
  }
  msg.table.inliers = 41234;

  tabletop_shapes::Cube cube;
  cube.header = msg.header;
  cube.pose.position.x = 0.05;
  cube.pose.position.y = 0.12;
  cube.pose.position.z = 1.1;
  cube.pose.orientation.w = 0.7071067811865476;
  cube.pose.orientation.z = 0.7071067811865476;
  cube.dimensions.x = 0.15;
  cube.dimensions.y = 0.095;
  cube.dimensions.z = 0.05;
  cube.faces_seen = 2;
  cube.points = 1500;
  cube.rmse = 0.0021;
  cube.primitive.type = shape_msgs::SolidPrimitive::BOX;
  cube.primitive.dimensions = {0.15, 0.095, 0.05};
  msg.cubes.push_back(cube);

  tabletop_shapes::Cylinder cylinder;
  cylinder.header = msg.header;
  cylinder.pose.orientation.w = 1.0;
  cylinder.radius = 0.0415;
  cylinder.height = 0.16;
  cylinder.points = 900;
  cylinder.rmse = 0.0017;
  cylinder.primitive.type = shape_msgs::SolidPrimitive::CYLINDER;
  cylinder.primitive.dimensions = {0.16, 0.0415};
  msg.cylinders.push_back(cylinder);

  tabletop_shapes::Cone cone;
  cone.header = msg.header;
  cone.pose.orientation.w = 1.0;
  cone.radius_bottom = 0.03;
  cone.radius_top = 0.0375;
  cone.height = 0.18;
  cone.points = 800;
  cone.rmse = 0.0019;
  msg.cones.push_back(cone);

  // No model fitted this one, and it is cut by the image border along its x edge.
  tabletop_shapes::Cube bounding_box = cube;
  bounding_box.faces_seen = 0;
  bounding_box.bounding_box = true;
  bounding_box.reason = "no model fits: cube: only one vertical face seen; cylinder: diameter";
  bounding_box.truncated = true;
  bounding_box.dimensions_lower_bound = {true, false, false};
  msg.cubes.push_back(bounding_box);

  tabletop_shapes::UnfittedCluster unfitted;
  unfitted.centroid.x = -0.2;
  unfitted.points = 140;
  unfitted.reason = "no model fits: cube rmse 0.011 m, cylinder rmse 0.014 m";
  msg.unfitted.push_back(unfitted);
  return msg;
}

TEST(Messages, ObjectsRoundTripKeepsEveryField) {
  const tabletop_shapes::Objects in = makeObjects();
  const tabletop_shapes::Objects out = roundTrip(in);
  // The generated operator== compares every field, nested arrays included.
  EXPECT_TRUE(in == out);
  ASSERT_EQ(out.cubes.size(), 2u);
  EXPECT_FALSE(out.cubes[0].bounding_box || out.cubes[0].truncated);
  EXPECT_TRUE(out.cubes[1].bounding_box && out.cubes[1].truncated);
  EXPECT_EQ(out.cubes[1].reason, in.cubes[1].reason);
  EXPECT_TRUE(out.cubes[1].dimensions_lower_bound[0] && !out.cubes[1].dimensions_lower_bound[2]);
  EXPECT_DOUBLE_EQ(out.cubes[0].dimensions.y, 0.095);
  EXPECT_EQ(out.cubes[0].faces_seen, 2);
  EXPECT_EQ(out.cubes[0].primitive.type, shape_msgs::SolidPrimitive::BOX);
  ASSERT_EQ(out.cylinders.size(), 1u);
  EXPECT_DOUBLE_EQ(out.cylinders[0].radius, 0.0415);
  ASSERT_EQ(out.cones.size(), 1u);
  EXPECT_DOUBLE_EQ(out.cones[0].radius_top, 0.0375);
  ASSERT_EQ(out.table.hull.points.size(), 4u);
  EXPECT_FLOAT_EQ(out.table.hull.points[3].z, 1.15f);
  EXPECT_EQ(out.header.stamp, ros::Time(1700000000, 123456000));
  EXPECT_EQ(out.unfitted[0].reason, in.unfitted[0].reason);
}

TEST(Messages, EmptyObjectsRoundTrip) {
  tabletop_shapes::Objects in;
  in.header.frame_id = "base_link";
  in.table_found = false;
  in.reason = "no table: no plane with 500 inliers within 10 deg of up";
  in.table.reason = "no plane with 500 inliers within 10 deg of up";
  const tabletop_shapes::Objects out = roundTrip(in);
  EXPECT_TRUE(in == out);
  EXPECT_FALSE(out.table_found);
  EXPECT_EQ(out.reason, in.reason);
  EXPECT_EQ(out.table.reason, in.table.reason);
  EXPECT_TRUE(out.cubes.empty() && out.cylinders.empty() && out.cones.empty());
}

TEST(Messages, SerialisedSizeGrowsWithContent) {
  // A change of the message definitions that drops a field shows here too.
  tabletop_shapes::Objects empty;
  const tabletop_shapes::Objects full = makeObjects();
  EXPECT_GT(ros::serialization::serializationLength(full),
            ros::serialization::serializationLength(empty) + 3 * 56);
}

}  // namespace
