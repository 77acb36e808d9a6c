// Depth image (uint16 millimetres, 0 = no reading) -> organised point cloud in the camera
// optical frame (x right, y down, z forward), with the pinhole model a ROS camera_info carries.
// ROS-free and OpenNI2-free so that it can be unit-tested; the OpenNI2 driver nodelet uses it.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstdint>

namespace tabletop_shapes {

// Kinect v1 / Asus Xtion fields of view [rad], used when a device reports none (the OpenNI2
// Dummy device reports 0): fx = 640 / (2 tan(1.0145 / 2)) = 575.8 px at 640 x 480.
constexpr double kDefaultHorizontalFov = 1.0145;
constexpr double kDefaultVerticalFov = 0.7898;

struct PinholeIntrinsics {
  int width = 0;
  int height = 0;
  double fx = 0.0, fy = 0.0;  // [px]
  double cx = 0.0, cy = 0.0;  // principal point [px], pixel centres at integer coordinates
};

// Intrinsics from the fields of view [rad], as openni2_camera computes them: square focal
// lengths from each FOV, principal point at the image centre ((W - 1) / 2, (H - 1) / 2). A
// field of view that is not in (0, pi) is replaced by the Kinect default; `used_default` (if
// given) says whether that happened.
PinholeIntrinsics intrinsicsFromFieldOfView(int width, int height, double horizontal_fov,
                                            double vertical_fov, bool* used_default = nullptr);

// openni2_camera's depth correction: z' = (z + offset_mm) * scaling for valid pixels (z > 0),
// clamped to 1 .. 65535 mm; invalid pixels stay 0.
struct DepthCorrection {
  int offset_mm = 0;
  double scaling = 1.0;
  bool isIdentity() const { return offset_mm == 0 && scaling == 1.0; }
};
void correctDepth(uint16_t* depth_mm, int pixel_count, const DepthCorrection& correction);

// Back-projects every pixel through its centre: z = depth * 1 mm, x = (u - cx) z / fx,
// y = (v - cy) z / fy; NaN where depth is 0. The cloud is organised (width x height of the
// intrinsics), is_dense = false.
void depthToCloud(const uint16_t* depth_mm, const PinholeIntrinsics& intrinsics,
                  pcl::PointCloud<pcl::PointXYZ>& cloud);

// The same with colour from an RGB888 image registered to the depth image (the same view); a
// colour image of another resolution is sampled at the proportional pixel (nearest), so VGA
// depth with SXGA colour works. `rgb` may be null: the points are then white.
void depthToCloud(const uint16_t* depth_mm, const PinholeIntrinsics& intrinsics, const uint8_t* rgb,
                  int rgb_width, int rgb_height, pcl::PointCloud<pcl::PointXYZRGB>& cloud);

}  // namespace tabletop_shapes
