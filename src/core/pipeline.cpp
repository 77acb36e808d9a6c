#include "tabletop_shapes/core/pipeline.h"

#include "tabletop_shapes/core/clustering.h"
#include "tabletop_shapes/core/support.h"
#include "tabletop_shapes/core/up_direction.h"

#include <algorithm>
#include <chrono>
#include <memory>

namespace tabletop_shapes {
namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// A bottle's neck (with its cap) meets the shoulder at a concave seam: the split
// (splitAtConcaveSeams) cuts it off and supportPlanes stands it on the shoulder, a round solid
// of its own (on rendered RealSense scenes, 15 of 40 such necks, r 1.7-2.3 cm, h 4-6 cm, and
// their bottles 4-6 cm short). A solid standing on a wider round one, on its axis (within
// kNeckAxisOffset of the lower one's radius) and starting within kNeckGap of its top, is that
// neck: the two clusters are one object again, fitted as one on the lower one's support. A box
// below (a can standing on a box) keeps them apart.
constexpr float kNeckAxisOffset = 0.5f;
constexpr float kNeckGap = 0.03f;  // [m]
// An object rests on another when its bottom lies this far above the table [m].
constexpr float kNeckLift = 0.01f;

bool isRound(const ShapeFit& fit) {
  return fit.ok && (fit.type == ShapeType::Cylinder || fit.type == ShapeType::Cone);
}
// Half the widest horizontal extent of a fitted solid.
float widestRadius(const ShapeFit& fit) {
  if (fit.type == ShapeType::Cube) return 0.5f * fit.dimensions.head<2>().maxCoeff();
  return fit.type == ShapeType::Cone ? std::max(fit.radius_bottom, fit.radius_top) : fit.radius;
}

// The index of the round solid whose neck fits[neck] is, or -1. The neck may be any fitted solid
// resting above the table: a neck 2-3 cm across came out a box too.
int bodyOfNeck(const std::vector<ShapeFit>& fits, size_t neck, const Plane& table) {
  const ShapeFit& upper = fits[neck];
  const Eigen::Vector3f up = table.normal.normalized();
  const float height = upper.type == ShapeType::Cube ? upper.dimensions.z() : upper.height;
  const float bottom = table.signedDistance(upper.center) - 0.5f * height;
  if (!upper.ok || !(bottom > kNeckLift)) return -1;
  for (size_t i = 0; i < fits.size(); ++i) {
    const ShapeFit& lower = fits[i];
    if (i == neck || !isRound(lower) || widestRadius(upper) >= widestRadius(lower)) continue;
    const float top = table.signedDistance(lower.center) + 0.5f * lower.height;
    const Eigen::Vector3f offset = upper.center - lower.center;
    const float axis_offset = (offset - up.dot(offset) * up).norm();
    if (std::abs(bottom - top) <= kNeckGap &&
        axis_offset <= kNeckAxisOffset * widestRadius(lower)) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

// Joins every neck to its body (bodyOfNeck) when the joined cluster fits a round solid.
void rejoinNecks(const ShapeEstimator& estimator, const Plane& table, const ViewBounds& view,
                 std::vector<CloudPtr>& clusters, std::vector<Plane>& supports,
                 std::vector<ShapeFit>& fits) {
  for (size_t neck = 0; neck < fits.size(); ++neck) {
    const int body = bodyOfNeck(fits, neck, table);
    if (body < 0) continue;
    auto joined = std::make_shared<Cloud>(*clusters[body]);
    *joined += *clusters[neck];
    ShapeFit fit = estimator.estimate(joined, supports[body], &view);
    if (!isRound(fit)) continue;
    clusters[body] = joined;
    fits[body] = fit;
    clusters.erase(clusters.begin() + neck);
    supports.erase(supports.begin() + neck);
    fits.erase(fits.begin() + neck);
    neck = static_cast<size_t>(-1);  // start over: indices moved
  }
}

}  // namespace

Pipeline::Pipeline(const PipelineParams& params) : filtered_(std::make_shared<Cloud>()) {
  setParams(params);
}

void Pipeline::setParams(const PipelineParams& params) {
  params_ = params;
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
  result.view = viewBoundsOf(cloud);
  result.view.point_spacing = params_.preprocess.leaf_size;
  preprocessor_.apply(cloud, *filtered_);
  result.times.preprocess_ms = msSince(stage);

  stage = Clock::now();
  TableParams table_params = params_.table;
  if (params_.auto_up && !estimateUp(filtered_, table_params, table_params.up)) {
    result.table.reason = "no large plane with the camera above it to take 'up' from";
  } else {
    result.up = table_params.up;
    result.table = TableSegmenter(table_params).segment(filtered_);
    if (params_.check_up && !params_.auto_up) {
      result.up_warning = checkUpAgainstScene(filtered_, table_params, result.table).warning;
    }
  }
  result.times.table_ms = msSince(stage);

  if (result.table.found && result.table.object_points) {
    stage = Clock::now();
    result.clusters =
        extractClusters(result.table.object_points, params_.clustering, &result.table.plane);
    result.times.clustering_ms = msSince(stage);

    stage = Clock::now();
    std::vector<Plane> supports = supportPlanes(result.clusters, result.table.plane);
    result.objects = estimator_.estimateAll(result.clusters, supports, &result.view);
    rejoinNecks(estimator_, result.table.plane, result.view, result.clusters, supports,
                result.objects);
    result.times.shapes_ms = msSince(stage);
  }
  result.times.total_ms = msSince(start);
  return result;
}

}  // namespace tabletop_shapes
