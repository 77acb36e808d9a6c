#include "tabletop_shapes/core/pipeline.h"

#include "tabletop_shapes/core/clustering.h"
#include "tabletop_shapes/core/object_fitting.h"
#include "tabletop_shapes/core/up_direction.h"

#include <chrono>

namespace tabletop_shapes {
namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

Pipeline::Pipeline(const PipelineParams& params) : filtered_(std::make_shared<Cloud>()) {
  setParams(params);
}

void Pipeline::setParams(const PipelineParams& params) {
  params_ = params;
  up_estimate_ = UpEstimate();  // an estimate made with other parameters
  preprocessor_.setParams(params.preprocess);
  estimator_.setParams(params.shapes);
}

SceneResult Pipeline::process(const pcl::PointCloud<pcl::PointXYZ>& cloud) {
  return processImpl(cloud);
}
SceneResult Pipeline::process(const pcl::PointCloud<pcl::PointXYZRGB>& cloud) {
  return processImpl(cloud);
}

template <typename PointT>
SceneResult Pipeline::processImpl(const pcl::PointCloud<PointT>& cloud) {
  SceneResult result;
  const auto start = Clock::now();

  auto stage = Clock::now();
  preprocessor_.apply(cloud, *filtered_, &result.view);  // the view bounds from the same pass
  result.view.point_spacing = params_.preprocess.leaf_size;
  result.times.preprocess_ms = msSince(stage);

  stage = Clock::now();
  TableParams table_params = params_.table;
  if (params_.auto_up) {
    if (up_estimate_.segment(filtered_, table_params, result.table)) result.up = table_params.up;
  } else {
    result.up = table_params.up;
    result.table = TableSegmenter(table_params).segment(filtered_);
    if (params_.check_up) {
      result.up_warning = checkUpAgainstScene(filtered_, table_params, result.table).warning;
    }
  }
  result.times.table_ms = msSince(stage);

  if (result.table.found && result.table.object_points) {
    stage = Clock::now();
    result.clusters =
        extractClusters(result.table.object_points, params_.clustering, &result.table.plane);
    rejectClustersOffTheTable(result.clusters, result.table.plane, result.table.hull,
                              result.table.depth_noise_at_one_metre, params_.table.hull_margin,
                              result.table.object_points->sensor_origin_.head<3>(), &result.view,
                              result.rejected);
    result.times.clustering_ms = msSince(stage);

    stage = Clock::now();
    result.objects = fitObjects(estimator_, result.table.plane, result.view, result.clusters);
    result.times.shapes_ms = msSince(stage);
  }
  result.times.total_ms = msSince(start);
  return result;
}

}  // namespace tabletop_shapes
