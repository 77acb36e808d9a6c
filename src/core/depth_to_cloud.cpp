#include "tabletop_shapes/core/depth_to_cloud.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace tabletop_shapes {
namespace {

bool validFov(double fov) { return std::isfinite(fov) && fov > 1e-3 && fov < 3.1; }

// Shared loop of both conversions: `set_point(index, x, y, z, valid)` per pixel.
template <typename SetPoint>
void backProject(const uint16_t* depth_mm, const PinholeIntrinsics& intrinsics,
                 SetPoint set_point) {
  const float inverse_fx = static_cast<float>(1.0 / intrinsics.fx);
  const float inverse_fy = static_cast<float>(1.0 / intrinsics.fy);
  const float cx = static_cast<float>(intrinsics.cx);
  const float cy = static_cast<float>(intrinsics.cy);
  for (int v = 0; v < intrinsics.height; ++v) {
    const float ray_y = (static_cast<float>(v) - cy) * inverse_fy;
    for (int u = 0; u < intrinsics.width; ++u) {
      const int index = v * intrinsics.width + u;
      const uint16_t raw = depth_mm[index];
      if (raw == 0) {
        set_point(index, 0.0f, 0.0f, 0.0f, false);
        continue;
      }
      const float z = static_cast<float>(raw) * 0.001f;
      set_point(index, (static_cast<float>(u) - cx) * inverse_fx * z, ray_y * z, z, true);
    }
  }
}

// The back-projected position, NaN for a pixel without depth.
template <typename PointT>
void setPosition(float x, float y, float z, bool valid, PointT& p) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  p.x = valid ? x : nan;
  p.y = valid ? y : nan;
  p.z = valid ? z : nan;
  p.data[3] = 1.0f;  // PCL's homogeneous coordinate
}

template <typename PointT>
void resizeOrganised(const PinholeIntrinsics& intrinsics, pcl::PointCloud<PointT>& cloud) {
  cloud.resize(static_cast<size_t>(intrinsics.width) * static_cast<size_t>(intrinsics.height));
  // PCL points have padding that their constructors leave uninitialised, and pcl_ros sends
  // whole points: zeroed, a published cloud carries no stale heap bytes (valgrind was right).
  std::memset(static_cast<void*>(cloud.points.data()), 0, cloud.size() * sizeof(PointT));
  cloud.width = static_cast<uint32_t>(intrinsics.width);
  cloud.height = static_cast<uint32_t>(intrinsics.height);
  cloud.is_dense = false;
}

}  // namespace

PinholeIntrinsics intrinsicsFromFieldOfView(int width, int height, double horizontal_fov,
                                            double vertical_fov, bool* used_default) {
  const bool fallback = !validFov(horizontal_fov) || !validFov(vertical_fov);
  if (fallback) {
    horizontal_fov = kDefaultHorizontalFov;
    vertical_fov = kDefaultVerticalFov;
  }
  if (used_default) *used_default = fallback;
  PinholeIntrinsics intrinsics;
  intrinsics.width = width;
  intrinsics.height = height;
  intrinsics.fx = width / (2.0 * std::tan(horizontal_fov / 2.0));
  intrinsics.fy = height / (2.0 * std::tan(vertical_fov / 2.0));
  intrinsics.cx = (width - 1) / 2.0;
  intrinsics.cy = (height - 1) / 2.0;
  return intrinsics;
}

void correctDepth(uint16_t* depth_mm, int pixel_count, const DepthCorrection& correction) {
  if (correction.isIdentity()) return;
  for (int i = 0; i < pixel_count; ++i) {
    if (depth_mm[i] == 0) continue;
    const double corrected = (depth_mm[i] + correction.offset_mm) * correction.scaling;
    depth_mm[i] = static_cast<uint16_t>(std::clamp(std::lround(corrected), 1l, 65535l));
  }
}

void depthToCloud(const uint16_t* depth_mm, const PinholeIntrinsics& intrinsics,
                  pcl::PointCloud<pcl::PointXYZ>& cloud) {
  resizeOrganised(intrinsics, cloud);
  backProject(depth_mm, intrinsics, [&](int index, float x, float y, float z, bool valid) {
    auto& p = cloud[index];
    setPosition(x, y, z, valid, p);
  });
}

void depthToCloud(const uint16_t* depth_mm, const PinholeIntrinsics& intrinsics, const uint8_t* rgb,
                  int rgb_width, int rgb_height, pcl::PointCloud<pcl::PointXYZRGB>& cloud) {
  resizeOrganised(intrinsics, cloud);
  const bool same_size = rgb_width == intrinsics.width && rgb_height == intrinsics.height;
  backProject(depth_mm, intrinsics, [&](int index, float x, float y, float z, bool valid) {
    auto& p = cloud[index];
    setPosition(x, y, z, valid, p);
    p.a = 255;
    if (!rgb) {
      p.r = p.g = p.b = 255;
      return;
    }
    int rgb_index = index;
    if (!same_size) {
      const int u = index % intrinsics.width, v = index / intrinsics.width;
      rgb_index =
          (v * rgb_height / intrinsics.height) * rgb_width + u * rgb_width / intrinsics.width;
    }
    p.r = rgb[3 * rgb_index];
    p.g = rgb[3 * rgb_index + 1];
    p.b = rgb[3 * rgb_index + 2];
  });
}

}  // namespace tabletop_shapes
