// libFuzzer target: the core pipeline (preprocess, table, clusters, shapes) on raw point
// buffers: the first byte picks the image width (organised clouds) and whether up is
// estimated, the rest are float32 x y z triples (NaN, inf, huge and denormal values included).
#include "tabletop_shapes/core/pipeline.h"

#include <cstring>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const unsigned width_choice = data[0] & 0x1f;
  const bool auto_up = data[0] & 0x80;
  const size_t points = std::min<size_t>((size - 1) / 12, 20000);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.resize(points);
  for (size_t i = 0; i < points; ++i) {
    std::memcpy(cloud.points[i].data, data + 1 + 12 * i, 12);
  }
  if (width_choice > 1 && points % width_choice == 0 && points > 0) {
    cloud.width = width_choice;
    cloud.height = static_cast<uint32_t>(points / width_choice);
  }
  cloud.is_dense = false;
  tabletop_shapes::PipelineParams params;
  params.auto_up = auto_up;
  params.table.min_inliers = 20;  // small inputs can hold a table: reach the later stages
  params.clustering.min_size = 10;
  tabletop_shapes::Pipeline pipeline(params);
  pipeline.process(cloud);
  return 0;
}
