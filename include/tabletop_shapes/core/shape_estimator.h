// §3: one cluster in, one fitted solid out. Normals by MLS; the box and the round model (cylinder
// or cone) are both fitted and the one whose surface the points follow more closely wins (a
// wrong guess of the §3.1 predictor falls back to the other model that way).
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

struct ShapeEstimatorParams {
  NormalParams normals;
  PredictorParams predictor;
  CubeParams cube;
  CylinderParams cylinder;
  ConeParams cone;
};

class ShapeEstimator {
 public:
  explicit ShapeEstimator(const ShapeEstimatorParams& params = {}) : params_(params) {}
  void setParams(const ShapeEstimatorParams& params) { params_ = params; }
  const ShapeEstimatorParams& params() const { return params_; }

  // Never throws: a cluster no model fits comes back as Unknown, ok == false, with the reason
  // of every model tried; its center is the centroid of the cluster.
  ShapeFit estimate(const CloudConstPtr& cluster, const Plane& table) const;
  // estimate() of every cluster, in the same order; the clusters are fitted in parallel, one
  // per core at a time (largest first when they come largest first).
  std::vector<ShapeFit> estimateAll(const std::vector<CloudPtr>& clusters,
                                    const Plane& table) const;

 private:
  ShapeEstimatorParams params_;
};

}  // namespace tabletop_shapes
