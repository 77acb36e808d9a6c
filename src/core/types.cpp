#include "tabletop_shapes/core/types.h"

#include "tabletop_shapes/core/parallel.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

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
  // Per band of rows, on all cores: the extreme tangents, and each row's pixel size (tan x
  // grows by 1 / fx per column), from rows that hold two valid points.
  struct Band {
    float min_x = std::numeric_limits<float>::max(), max_x = -min_x;
    float min_y = min_x, max_y = -min_x, min_z = min_x;
  };
  const unsigned threads = workerThreads();
  const size_t bands = threads > 1 ? std::min<size_t>(cloud.height, 4 * threads) : 1;
  std::vector<Band> band_bounds(bands);
  std::vector<double> row_pixel(cloud.height);
  std::vector<char> row_has_pixel(cloud.height, 0);
  parallelFor(
      bands,
      [&](size_t band) {
        Band& b = band_bounds[band];
        const uint32_t first_row = static_cast<uint32_t>(band * cloud.height / bands),
                       end_row = static_cast<uint32_t>((band + 1) * cloud.height / bands);
        for (uint32_t row = first_row; row < end_row; ++row) {
          int first = -1, last = -1;
          for (uint32_t column = 0; column < cloud.width; ++column) {
            const PointT& p = cloud.points[row * cloud.width + column];
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || p.z <= 0.0f) {
              continue;
            }
            b.min_x = std::min(b.min_x, p.x / p.z);
            b.max_x = std::max(b.max_x, p.x / p.z);
            b.min_y = std::min(b.min_y, p.y / p.z);
            b.min_z = std::min(b.min_z, p.z);
            b.max_y = std::max(b.max_y, p.y / p.z);
            if (first < 0) first = static_cast<int>(column);
            last = static_cast<int>(column);
          }
          row_has_pixel[row] = last > first;
          if (last > first) {
            const PointT& a = cloud.points[row * cloud.width + first];
            const PointT& c = cloud.points[row * cloud.width + last];
            row_pixel[row] = (c.x / c.z - a.x / a.z) / (last - first);
          }
        }
      },
      threads);
  Band all;
  for (const Band& b : band_bounds) {  // minima and maxima do not depend on the order
    all.min_x = std::min(all.min_x, b.min_x);
    all.max_x = std::max(all.max_x, b.max_x);
    all.min_y = std::min(all.min_y, b.min_y);
    all.max_y = std::max(all.max_y, b.max_y);
    all.min_z = std::min(all.min_z, b.min_z);
  }
  double pixel_sum = 0.0;  // in row order: the same sum whatever the bands
  long pixel_count = 0;
  for (uint32_t row = 0; row < cloud.height; ++row) {
    if (!row_has_pixel[row]) continue;
    pixel_sum += row_pixel[row];
    ++pixel_count;
  }
  if (pixel_count == 0 || !(all.max_x > all.min_x) || !(all.max_y > all.min_y)) return view;
  view.known = true;
  view.min_tan_x = all.min_x;
  view.max_tan_x = all.max_x;
  view.min_tan_y = all.min_y;
  view.max_tan_y = all.max_y;
  view.pixel_tan = static_cast<float>(pixel_sum / pixel_count);
  view.min_depth = all.min_z;
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
