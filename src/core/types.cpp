#include "tabletop_shapes/core/types.h"

#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/view_bounds.h"

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

void ViewBoundsGatherer::reset(size_t bands, size_t rows) {
  bands_.assign(bands, Band());
  row_pixel_.assign(rows, 0.0);
  row_has_pixel_.assign(rows, 0);
}

ViewBounds ViewBoundsGatherer::bounds() const {
  ViewBounds view;
  Band all;
  for (const Band& b : bands_) {  // minima and maxima do not depend on the order
    all.min_x_ = std::min(all.min_x_, b.min_x_);
    all.max_x_ = std::max(all.max_x_, b.max_x_);
    all.min_y_ = std::min(all.min_y_, b.min_y_);
    all.max_y_ = std::max(all.max_y_, b.max_y_);
    all.min_z_ = std::min(all.min_z_, b.min_z_);
  }
  double pixel_sum = 0.0;  // in row order: the same sum whatever the bands
  long pixel_count = 0;
  for (size_t row = 0; row < row_pixel_.size(); ++row) {
    if (!row_has_pixel_[row]) continue;
    pixel_sum += row_pixel_[row];
    ++pixel_count;
  }
  if (pixel_count == 0 || !(all.max_x_ > all.min_x_) || !(all.max_y_ > all.min_y_)) return view;
  view.known = true;
  view.min_tan_x = all.min_x_;
  view.max_tan_x = all.max_x_;
  view.min_tan_y = all.min_y_;
  view.max_tan_y = all.max_y_;
  view.pixel_tan = static_cast<float>(pixel_sum / pixel_count);
  view.min_depth = all.min_z_;
  return view;
}

namespace {

template <typename PointT>
ViewBounds viewBoundsOfImpl(const pcl::PointCloud<PointT>& cloud) {
  if (cloud.height < 2 || cloud.width < 2) return ViewBounds();
  // Bands of rows on all cores.
  const unsigned threads = workerThreads();
  const size_t bands = threads > 1 ? std::min<size_t>(cloud.height, 4 * threads) : 1;
  ViewBoundsGatherer gatherer;
  gatherer.reset(bands, cloud.height);
  parallelFor(
      bands,
      [&](size_t band) {
        ViewBoundsGatherer::Band b;
        const uint32_t first_row = static_cast<uint32_t>(band * cloud.height / bands),
                       end_row = static_cast<uint32_t>((band + 1) * cloud.height / bands);
        for (uint32_t row = first_row; row < end_row; ++row) {
          for (uint32_t column = 0; column < cloud.width; ++column) {
            const PointT& p = cloud.points[row * cloud.width + column];
            if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) {
              b.add(static_cast<int>(column), p.x, p.y, p.z);
            }
          }
          gatherer.endRow(b, row);
        }
        gatherer.setBand(band, b);
      },
      threads);
  return gatherer.bounds();
}

}  // namespace

ViewBounds viewBoundsOf(const pcl::PointCloud<pcl::PointXYZ>& cloud) {
  return viewBoundsOfImpl(cloud);
}
ViewBounds viewBoundsOf(const pcl::PointCloud<pcl::PointXYZRGB>& cloud) {
  return viewBoundsOfImpl(cloud);
}

}  // namespace tabletop_shapes
