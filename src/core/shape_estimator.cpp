#include "tabletop_shapes/core/shape_estimator.h"

#include "tabletop_shapes/core/cube_fit.h"
#include "tabletop_shapes/core/cylinder_fit.h"
#include "tabletop_shapes/core/normals.h"
#include "tabletop_shapes/core/predictor.h"

#include <sstream>

namespace tabletop_shapes {
namespace {

ShapeFit unknown(const Cloud& cluster, const std::string& reason) {
  ShapeFit fit;
  fit.type = ShapeType::Unknown;
  fit.reason = reason;
  fit.points = static_cast<int>(cluster.size());
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  for (const auto& p : cluster.points) sum += p.getVector3fMap();
  if (!cluster.empty()) fit.center = sum / static_cast<float>(cluster.size());
  return fit;
}

// A round fit rests on the side-wall points only. Resting on a tenth of the cluster or less it
// describes a sliver: seen on a box at 0.5 m, a cylinder through 11 of its ~900 points fitted
// to 1.9 mm, better than the box could. Real cylinders and cones use 30-90 % of their points.
constexpr float kMinFitFraction = 0.1f;

ShapeFit checkSupport(ShapeFit fit, size_t cluster_size) {
  if (fit.ok && fit.points < kMinFitFraction * static_cast<float>(cluster_size)) {
    fit.ok = false;
    fit.reason = "the " + std::string(shapeTypeName(fit.type)) + " rests on only " +
                 std::to_string(fit.points) + " of " + std::to_string(cluster_size) + " points";
  }
  return fit;
}

}  // namespace

ShapeFit ShapeEstimator::estimate(const CloudConstPtr& cluster, const Plane& table) const {
  if (!cluster || cluster->size() < 10) {
    return unknown(cluster ? *cluster : Cloud(), "too few points to fit a model");
  }
  NormalCloud normals;
  estimateNormalsMLS(cluster, params_.normals, normals);
  if (normals.size() < 10) return unknown(*cluster, "too few points with a normal");

  const Prediction prediction = predictShape(normals, params_.predictor);
  auto fitAs = [&](ShapeType type) {
    return checkSupport(type == ShapeType::Cube
                            ? fitCube(normals, table, params_.cube)
                            : fitRoundObject(normals, table, params_.cylinder, params_.cone),
                        normals.size());
  };
  const ShapeType first =
      prediction.guess == ShapeType::Cube ? ShapeType::Cube : ShapeType::Cylinder;
  const ShapeType second = first == ShapeType::Cube ? ShapeType::Cylinder : ShapeType::Cube;

  ShapeFit best = fitAs(first);
  if (best.ok && best.rmse <= params_.predictor.fallback_rmse) return best;

  // The guess fits badly (or not at all): try the other model, keep the lower residual.
  ShapeFit other = fitAs(second);
  if (other.ok && (!best.ok || other.rmse < best.rmse)) best = other;
  if (best.ok) return best;

  std::ostringstream reason;
  reason << "no model fits: " << shapeTypeName(first) << ": " << best.reason << "; "
         << shapeTypeName(second) << ": " << other.reason;
  return unknown(*cluster, reason.str());
}

}  // namespace tabletop_shapes
