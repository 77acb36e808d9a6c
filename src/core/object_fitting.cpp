#include "tabletop_shapes/core/object_fitting.h"

#include "tabletop_shapes/core/neck_join.h"
#include "tabletop_shapes/core/support.h"

namespace tabletop_shapes {

std::vector<ShapeFit> fitObjects(const ShapeEstimator& estimator, const Plane& table,
                                 const ViewBounds& view, std::vector<CloudPtr>& clusters) {
  // The clusters are in the camera's optical frame (as `view` is): the camera is the origin.
  std::vector<Plane> supports = supportPlanes(clusters, table, Eigen::Vector3f::Zero());
  std::vector<ShapeFit> fits = estimator.estimateAll(clusters, supports, &view);
  rejoinNecks(estimator, table, view, clusters, supports, fits);
  return fits;
}

}  // namespace tabletop_shapes
