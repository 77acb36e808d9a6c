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
  // A fitted solid may reach at most this far beyond the cluster's points [m]: along the
  // table and up for any solid, across the line of sight for the diameter of a round one
  // (its back is hidden). A model breaking this is rejected with the reason.
  float max_overreach = 0.005f;
  // Active-stereo cameras (RealSense D4xx) smear a near surface's depth over up to this many
  // pixels beyond its silhouette (their correlation window: "foreground fattening"); 0 for
  // structured light (Kinect v1, Xtion). Points within that band of a cluster's sides, across
  // the line of sight, are left out of the fit: an 18 mm marker's points spanned 30-36 mm. A
  // thin upright cylinder (under 14 px across) takes half its median width over height slices,
  // less the smear, as its radius (its circle is depth noise).
  float edge_bleed_px = 0.0f;
  // The camera's near limit, the nearest depth it measures [m] (Kinect v1: 0.45, RealSense
  // D435: 0.28); 0: unknown. An object holding a frame's nearest point is taken as cut by it
  // (truncated, towards the camera) only when that point lies at this limit; unknown, when it
  // lies within 0.6 m.
  float near_limit = 0.0f;
};

class ShapeEstimator {
 public:
  explicit ShapeEstimator(const ShapeEstimatorParams& params = {}) : params_(params) {}
  void setParams(const ShapeEstimatorParams& params) { params_ = params; }
  const ShapeEstimatorParams& params() const { return params_; }

  // Never throws. A cluster no model fits (or whose every model breaks max_overreach) comes
  // back as its bounding box (Cube, bounding_box == true) with the reason of every model tried;
  // only a cluster too small for that is Unknown, ok == false, centred on its centroid.
  // `view` (optional, the frame's ViewBounds) marks objects cut by the image border.
  ShapeFit estimate(const CloudConstPtr& cluster, const Plane& table,
                    const ViewBounds* view = nullptr) const;
  // estimate() of every cluster on its support plane (supports[i] for clusters[i]), in the same
  // order; the clusters are fitted in parallel, one per core at a time (largest first when they
  // come largest first).
  std::vector<ShapeFit> estimateAll(const std::vector<CloudPtr>& clusters,
                                    const std::vector<Plane>& supports,
                                    const ViewBounds* view = nullptr) const;

 private:
  ShapeEstimatorParams params_;
};

}  // namespace tabletop_shapes
