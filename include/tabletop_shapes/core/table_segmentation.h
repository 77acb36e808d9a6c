// §2.2-2.4: the support plane, its convex hull, the object points above it, outlier removal.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

struct TableResult {
  bool found = false;
  std::string reason;                 // why no table was found (found == false)
  Plane plane;                        // normal points up (same side as TableParams::up)
  int inliers = 0;                    // points on the table plane
  std::vector<Eigen::Vector3f> hull;  // convex hull of the inliers, on the plane, ordered
  // RMS distance of the nearer half of the inliers to the plane over their range squared: the
  // sensor's depth noise at 1 m for noise growing with the square of the range [m].
  float depth_noise_at_one_metre = 0.0f;
  CloudPtr table_points;   // the inliers
  CloudPtr object_points;  // above the table, inside hull - margin, outliers removed
};

class TableSegmenter {
 public:
  explicit TableSegmenter(const TableParams& params = {}) : params_(params) {}
  void setParams(const TableParams& params) { params_ = params; }
  const TableParams& params() const { return params_; }

  // The support plane is the plane the objects stand on: among the planes whose normal is
  // within up_tolerance_deg of up and that have >= min_inliers points, the highest one
  // (along up) with objects on it, not simply the largest one (the floor often is).
  TableResult segment(const CloudConstPtr& cloud) const;

 private:
  TableParams params_;
};

// Ordinary least squares refinement of a plane on its inliers (eq. 4-8), handling d = 0.
// Returns false when the points are degenerate (fewer than 3, collinear).
bool refinePlaneOLS(const Cloud& points, const std::vector<int>& indices, Plane& plane);

// §2.4 statistical outlier removal: keep points whose mean distance to their k nearest
// neighbours is below mu + alpha * sigma.
void removeStatisticalOutliers(const CloudConstPtr& in, int k, float alpha, Cloud& out);

// Estimates the world's up direction in the cloud frame, for a camera of unknown tilt: the
// candidates are large planes with the camera (the origin) above them; the support plane is
// chosen as TableSegmenter does. Returns false when no candidate plane is found.
bool estimateUp(const CloudConstPtr& cloud, const TableParams& params, Eigen::Vector3f& up);

// True when `table` holds more than half of the cloud's finite points and is a plane estimateUp
// takes up from (the camera above it, its normal up in the image): no other direction's planes
// can outnumber it, so estimateUp's answer is this table's normal (up to the up_tolerance_deg
// it allows among parallel planes) without its plane search.
bool tableIsTheDominantLevelPlane(const Cloud& cloud, const TableResult& table);

}  // namespace tabletop_shapes
