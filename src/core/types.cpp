#include "tabletop_shapes/core/types.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tabletop_shapes {

const char* shapeTypeName(ShapeType type) {
  switch (type) {
    case ShapeType::Cube:
      return "cube";
    case ShapeType::Cylinder:
      return "cylinder";
    case ShapeType::Cone:
      return "cone";
    case ShapeType::Unknown:
      break;
  }
  return "unknown";
}

}  // namespace tabletop_shapes

namespace tabletop_shapes {
namespace {

template <typename PointT>
ViewBounds viewBoundsOfImpl(const pcl::PointCloud<PointT>& cloud) {
  ViewBounds view;
  if (cloud.height < 2 || cloud.width < 2) return view;
  float min_x = std::numeric_limits<float>::max(), max_x = -min_x;
  float min_y = min_x, max_y = -min_x, min_z = min_x;
  // Pixel size from rows that hold two valid points: tan x grows by 1 / fx per column.
  double pixel_sum = 0.0;
  long pixel_count = 0;
  for (uint32_t row = 0; row < cloud.height; ++row) {
    int first = -1, last = -1;
    for (uint32_t column = 0; column < cloud.width; ++column) {
      const PointT& p = cloud.points[row * cloud.width + column];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || p.z <= 0.0f) {
        continue;
      }
      min_x = std::min(min_x, p.x / p.z);
      max_x = std::max(max_x, p.x / p.z);
      min_y = std::min(min_y, p.y / p.z);
      min_z = std::min(min_z, p.z);
      max_y = std::max(max_y, p.y / p.z);
      if (first < 0) first = static_cast<int>(column);
      last = static_cast<int>(column);
    }
    if (last > first) {
      const PointT& a = cloud.points[row * cloud.width + first];
      const PointT& b = cloud.points[row * cloud.width + last];
      pixel_sum += (b.x / b.z - a.x / a.z) / (last - first);
      ++pixel_count;
    }
  }
  if (pixel_count == 0 || !(max_x > min_x) || !(max_y > min_y)) return view;
  view.known = true;
  view.min_tan_x = min_x;
  view.max_tan_x = max_x;
  view.min_tan_y = min_y;
  view.max_tan_y = max_y;
  view.pixel_tan = static_cast<float>(pixel_sum / pixel_count);
  view.min_depth = min_z;
  return view;
}

}  // namespace

ViewBounds viewBoundsOf(const pcl::PointCloud<pcl::PointXYZ>& cloud) {
  return viewBoundsOfImpl(cloud);
}
ViewBounds viewBoundsOf(const pcl::PointCloud<pcl::PointXYZRGB>& cloud) {
  return viewBoundsOfImpl(cloud);
}

}  // namespace tabletop_shapes
