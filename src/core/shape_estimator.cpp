#include "tabletop_shapes/core/shape_estimator.h"

#include "tabletop_shapes/core/cube_fit.h"
#include "tabletop_shapes/core/cylinder_fit.h"
#include "tabletop_shapes/core/normals.h"
#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/predictor.h"

#include <algorithm>
#include <cmath>
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

// Points the model comparison is judged on: the closest 90 % to each model's surface. The rest
// may be flying pixels along the line of sight behind an edge: on a 5 cm box at 1.1 m, 5 % of
// the cluster, up to 10 cm off, which dominate any plain RMS.
constexpr float kComparedFraction = 0.9f;

// How closely the cluster follows the fitted solid, comparable between models: RMS distance of
// the closest kComparedFraction of all its points to the solid's surface. The fits' own rmse is
// not comparable: the box's covers all the points, flying pixels included, the round fit's only
// the side-wall points it kept. Cylinders through the sides of flat boxes at 0.7-1.25 m thus
// claimed 2.5-8.4 mm against the boxes' 4.9-14 mm, while 90 % of the points lay within
// 0.3-0.5 mm RMS of the boxes' surfaces and 1.1-14 mm of the cylinders' (corners stick out).
float surfaceResidual(const ShapeFit& fit, const NormalCloud& cluster) {
  std::vector<float> squared;
  squared.reserve(cluster.size());
  for (const auto& p : cluster.points) {
    const float distance = fit.type == ShapeType::Cube
                               ? distanceToBox(fit, p.getVector3fMap())
                               : distanceToRoundObject(fit, p.getVector3fMap());
    squared.push_back(distance * distance);
  }
  if (squared.empty()) return 0.0f;
  const size_t kept = std::max<size_t>(
      1, static_cast<size_t>(kComparedFraction * static_cast<float>(squared.size())));
  std::nth_element(squared.begin(), squared.begin() + (kept - 1), squared.end());
  double sum = 0.0;
  for (size_t i = 0; i < kept; ++i) sum += squared[i];
  return static_cast<float>(std::sqrt(sum / static_cast<double>(kept)));
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

  // Both models are fitted, as no residual of the guess alone tells a wrong guess: on the
  // rendered benchmark, right models follow their clusters to 0.15-1.5 mm (surfaceResidual),
  // wrong ones from 0.8 mm, and a cylinder on the sides of a 16.7 x 5.6 x 7.9 cm box at 1.4 m
  // had its own rmse at 1.3 mm. The model the points follow more closely wins; the guess only
  // orders the reasons of a failure.
  const ShapeFit guessed = fitAs(first);
  const ShapeFit other = fitAs(second);
  if (guessed.ok && other.ok) {
    return surfaceResidual(other, normals) < surfaceResidual(guessed, normals) ? other : guessed;
  }
  if (guessed.ok) return guessed;
  if (other.ok) return other;

  std::ostringstream reason;
  reason << "no model fits: " << shapeTypeName(first) << ": " << guessed.reason << "; "
         << shapeTypeName(second) << ": " << other.reason;
  return unknown(*cluster, reason.str());
}

std::vector<ShapeFit> ShapeEstimator::estimateAll(const std::vector<CloudPtr>& clusters,
                                                  const Plane& table) const {
  std::vector<ShapeFit> fits(clusters.size());
  parallelFor(clusters.size(), [&](size_t i) { fits[i] = estimate(clusters[i], table); });
  return fits;
}

}  // namespace tabletop_shapes
