// Depth image -> organised cloud (the OpenNI2 driver's conversion), against hand-computed points.
#include "tabletop_shapes/core/depth_to_cloud.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace tabletop_shapes {
namespace {

TEST(DepthToCloud, IntrinsicsFromKinectFieldOfView) {
  const PinholeIntrinsics k = intrinsicsFromFieldOfView(640, 480, 1.0145, 0.7898);
  EXPECT_NEAR(k.fx, 575.8, 0.2);  // the Kinect's well-known 575.8 px
  EXPECT_NEAR(k.fy, 575.8, 0.6);
  EXPECT_DOUBLE_EQ(k.cx, 319.5);
  EXPECT_DOUBLE_EQ(k.cy, 239.5);
  // Exact round trip of fx = W / (2 tan(hfov / 2)).
  const double hfov = 2.0 * std::atan(160.0 / 287.9);
  EXPECT_NEAR(intrinsicsFromFieldOfView(320, 240, hfov, hfov).fx, 287.9, 1e-9);
}

TEST(DepthToCloud, ZeroFieldOfViewFallsBackToTheKinect) {
  bool used_default = false;
  const PinholeIntrinsics k = intrinsicsFromFieldOfView(320, 240, 0.0, 0.0, &used_default);
  EXPECT_TRUE(used_default);
  EXPECT_NEAR(k.fx, 575.8 / 2.0, 0.1);
  intrinsicsFromFieldOfView(320, 240, NAN, 0.79, &used_default);
  EXPECT_TRUE(used_default);
  intrinsicsFromFieldOfView(320, 240, 1.0, 0.79, &used_default);
  EXPECT_FALSE(used_default);
}

TEST(DepthToCloud, KnownPixelsBecomeKnownPoints) {
  PinholeIntrinsics k;
  k.width = 4;
  k.height = 3;
  k.fx = 500.0;
  k.fy = 400.0;
  k.cx = 1.5;
  k.cy = 1.0;
  std::vector<uint16_t> depth(12, 0);
  depth[0 * 4 + 0] = 1000;  // (u 0, v 0) at 1 m
  depth[2 * 4 + 3] = 2500;  // (u 3, v 2) at 2.5 m
  depth[1 * 4 + 1] = 65535;
  pcl::PointCloud<pcl::PointXYZ> cloud;
  depthToCloud(depth.data(), k, cloud);
  ASSERT_EQ(cloud.width, 4u);
  ASSERT_EQ(cloud.height, 3u);
  EXPECT_FALSE(cloud.is_dense);
  EXPECT_NEAR(cloud.at(0, 0).x, (0 - 1.5) * 1.0 / 500.0, 1e-7);  // -3 mm
  EXPECT_NEAR(cloud.at(0, 0).y, (0 - 1.0) * 1.0 / 400.0, 1e-7);  // -2.5 mm
  EXPECT_NEAR(cloud.at(0, 0).z, 1.0, 1e-7);
  EXPECT_NEAR(cloud.at(3, 2).x, 1.5 * 2.5 / 500.0, 1e-7);
  EXPECT_NEAR(cloud.at(3, 2).y, 1.0 * 2.5 / 400.0, 1e-7);
  EXPECT_NEAR(cloud.at(3, 2).z, 2.5, 1e-6);
  EXPECT_NEAR(cloud.at(1, 1).z, 65.535, 1e-4);
  int nan_points = 0;
  for (const auto& p : cloud) nan_points += std::isnan(p.x) && std::isnan(p.y) && std::isnan(p.z);
  EXPECT_EQ(nan_points, 9);
}

TEST(DepthToCloud, ColourSameSizeAndScaled) {
  PinholeIntrinsics k;
  k.width = 2;
  k.height = 2;
  k.fx = k.fy = 100.0;
  k.cx = k.cy = 0.5;
  const std::vector<uint16_t> depth = {500, 0, 700, 800};
  std::vector<uint8_t> rgb(2 * 2 * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<uint8_t>(10 * i);
  pcl::PointCloud<pcl::PointXYZRGB> cloud;
  depthToCloud(depth.data(), k, rgb.data(), 2, 2, cloud);
  EXPECT_EQ(cloud.at(1, 1).r, 90);
  EXPECT_EQ(cloud.at(1, 1).g, 100);
  EXPECT_EQ(cloud.at(1, 1).b, 110);
  EXPECT_NEAR(cloud.at(1, 1).x, 0.5 * 0.8 / 100.0, 1e-7);
  EXPECT_TRUE(std::isnan(cloud.at(1, 0).z));
  EXPECT_EQ(cloud.at(1, 0).g, 40);  // colour is kept where depth is missing
  // Colour at twice the depth resolution: pixel (u, v) takes colour (2u, 2v).
  std::vector<uint8_t> big(4 * 4 * 3, 0);
  big[(2 * 4 + 2) * 3] = 200;  // colour (2, 2) -> depth (1, 1)
  depthToCloud(depth.data(), k, big.data(), 4, 4, cloud);
  EXPECT_EQ(cloud.at(1, 1).r, 200);
  EXPECT_EQ(cloud.at(0, 0).r, 0);
  // No colour image: white points.
  depthToCloud(depth.data(), k, nullptr, 0, 0, cloud);
  EXPECT_EQ(cloud.at(0, 0).r, 255);
}

TEST(DepthToCloud, OffsetAndScalingCorrection) {
  std::vector<uint16_t> depth = {0, 1000, 2000, 5, 65530};
  correctDepth(depth.data(), 5, DepthCorrection{10, 1.0});
  EXPECT_EQ(depth, (std::vector<uint16_t>{0, 1010, 2010, 15, 65535}));  // 0 stays invalid
  correctDepth(depth.data(), 5, DepthCorrection{-10, 0.5});
  EXPECT_EQ(depth, (std::vector<uint16_t>{0, 500, 1000, 3, 32763}));
  correctDepth(depth.data(), 5, DepthCorrection{-100, 1.0});  // clamps to 1 mm, never 0
  EXPECT_EQ(depth[3], 1);
}

}  // namespace
}  // namespace tabletop_shapes
