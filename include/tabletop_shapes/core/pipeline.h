// The whole chain of the paper in one call: preprocess -> table -> clustering -> shapes.
// Used by the estimate_shapes command and the benchmarks; the nodelets call the stages one by
// one instead, so that each runs in its own nodelet.
#pragma once

#include "tabletop_shapes/core/preprocess.h"
#include "tabletop_shapes/core/shape_estimator.h"
#include "tabletop_shapes/core/table_edge.h"
#include "tabletop_shapes/core/table_segmentation.h"
#include "tabletop_shapes/core/up_direction.h"

namespace tabletop_shapes {

struct PipelineParams {
  PreprocessParams preprocess;
  TableParams table;
  ClusteringParams clustering;
  ShapeEstimatorParams shapes;
  bool auto_up = false;  // estimate "up" from the scene instead of table.up
  // With a given up (auto_up false): compare it with the scene's (checkUpAgainstScene) and
  // fill SceneResult::up_warning when they disagree. Costs one more plane search.
  bool check_up = false;
};

struct StageTimes {
  double preprocess_ms = 0, table_ms = 0, clustering_ms = 0, shapes_ms = 0, total_ms = 0;
};

struct SceneResult {
  Eigen::Vector3f up = Eigen::Vector3f::Zero();  // the up direction used
  std::string up_warning;  // check_up: the given up does not fit the scene (why, with angles)
  ViewBounds view;         // bounds of the input's valid pixels (organised input), for cut objects
  TableResult table;
  std::vector<CloudPtr> clusters;  // the object clusters, largest first
  std::vector<ShapeFit> objects;   // one per cluster, same order; unfitted: Unknown + reason
  // Clusters that are no objects on the table (whyNotOnTheTable), each with the reason; not
  // fitted, not in `clusters`.
  std::vector<RejectedCluster> rejected;
  StageTimes times;
};

class Pipeline {
 public:
  explicit Pipeline(const PipelineParams& params = {});
  void setParams(const PipelineParams& params);
  const PipelineParams& params() const { return params_; }

  SceneResult process(const pcl::PointCloud<pcl::PointXYZ>& cloud);
  SceneResult process(const pcl::PointCloud<pcl::PointXYZRGB>& cloud);

 private:
  template <typename PointT>
  SceneResult processImpl(const pcl::PointCloud<PointT>& cloud);

  PipelineParams params_;
  Preprocessor preprocessor_;
  ShapeEstimator estimator_;
  UpEstimate up_estimate_;  // auto_up: held between frames of the stream
  CloudPtr filtered_;       // reused between frames
};

}  // namespace tabletop_shapes
