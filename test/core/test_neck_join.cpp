// rejoinNecks: a bottle's neck, split off at the shoulder and fitted apart, joins its body; a
// can standing on a box stays apart.
#include "tabletop_shapes/core/neck_join.h"

#include "tabletop_shapes/core/support.h"

#include <gtest/gtest.h>

#include <string>
#include <tuple>

#include "synthetic.h"

namespace tabletop_shapes {
namespace {

struct Fitted {
  std::vector<CloudPtr> clusters;
  std::vector<Plane> supports;
  std::vector<ShapeFit> fits;
};

// The table-frame clusters moved into the sampler's camera frame, on their supports, fitted.
Fitted fitInCameraFrame(std::vector<CloudPtr> clusters, const synthetic::Sampler& s,
                        const ShapeEstimator& estimator, Plane& table) {
  const Eigen::Isometry3f camera_from_table = synthetic::cameraFromTable(s);
  for (const CloudPtr& cluster : clusters) synthetic::transformCloud(camera_from_table, *cluster);
  table = synthetic::transformPlane(camera_from_table, synthetic::tablePlane());
  Fitted out;
  out.clusters = clusters;
  out.supports = supportPlanes(out.clusters, table, Eigen::Vector3f::Zero());
  out.fits = estimator.estimateAll(out.clusters, out.supports);
  return out;
}

// One piece of a bottle's wall: a truncated cone from `bottom` up, without the top disc that
// lies inside the bottle (the next piece covers it).
CloudPtr wallPiece(float r_bottom, float r_top, float height, float bottom,
                   const synthetic::Sampler& s) {
  const float r = 0.7f * r_top;  // the disc's points, not the wall's, inside this square
  return synthetic::withoutFootprint(
      synthetic::lifted(synthetic::roundObject(r_bottom, r_top, height, {0.0f, 0.0f}, s), bottom),
      -r, r, -r, r, bottom + height);
}

// Body d 65 mm up to 120 mm, a shoulder narrowing to d 24 mm at 155 mm, the neck up to 205 mm
// (the rendered bottle's proportions); the split parts them on the shoulder, at d 44 mm.
std::pair<CloudPtr, CloudPtr> bottleBodyAndNeck(const synthetic::Sampler& s) {
  auto body = wallPiece(0.0325f, 0.0325f, 0.12f, 0.0f, s);
  *body += *wallPiece(0.0325f, 0.022f, 0.018f, 0.12f, s);
  auto neck = wallPiece(0.022f, 0.012f, 0.017f, 0.138f, s);
  *neck +=
      *synthetic::lifted(synthetic::roundObject(0.012f, 0.012f, 0.05f, {0.0f, 0.0f}, s), 0.155f);
  return {body, neck};
}

// The bottle's body and neck as two clusters, fitted apart in the camera frame.
struct BottleParts {
  CloudPtr body, neck;
  Plane table;
  Fitted fitted;
};

BottleParts fitBottleParts(const ShapeEstimator& estimator) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  BottleParts parts;
  std::tie(parts.body, parts.neck) = bottleBodyAndNeck(s);
  parts.fitted = fitInCameraFrame({parts.body, parts.neck}, s, estimator, parts.table);
  return parts;
}

void expectOneBottle(const Fitted& fitted, const CloudPtr& body, const CloudPtr& neck) {
  ASSERT_EQ(fitted.fits.size(), 1u);
  ASSERT_EQ(fitted.clusters.size(), 1u);
  ASSERT_EQ(fitted.supports.size(), 1u);
  const ShapeFit& bottle = fitted.fits[0];
  EXPECT_EQ(bottle.type, ShapeType::Cylinder) << bottle.reason;
  EXPECT_NEAR(bottle.radius, 0.0325f, 0.002f);
  EXPECT_NEAR(bottle.height, 0.205f, 0.005f);
  EXPECT_EQ(fitted.clusters[0]->size(), body->size() + neck->size());
}

TEST(RejoinNecks, BottleNeckJoinsItsBody) {
  const ShapeEstimator estimator;
  BottleParts parts = fitBottleParts(estimator);
  Fitted& fitted = parts.fitted;
  const Plane& table = parts.table;
  ASSERT_EQ(fitted.fits.size(), 2u);
  ASSERT_TRUE(fitted.fits[1].ok) << fitted.fits[1].reason;

  auto describe = [&](const ShapeFit& f) {
    return std::string(shapeTypeName(f.type)) + " r " + std::to_string(f.radius) + " h " +
           std::to_string(f.height) + " bottom " +
           std::to_string(table.signedDistance(f.center) - 0.5f * f.height) + " " + f.reason;
  };
  const std::string before = describe(fitted.fits[0]) + "; " + describe(fitted.fits[1]);
  rejoinNecks(estimator, table, ViewBounds(), fitted.clusters, fitted.supports, fitted.fits);
  ASSERT_EQ(fitted.fits.size(), 1u) << before;
  expectOneBottle(fitted, parts.body, parts.neck);
}

TEST(RejoinNecks, NeckFittedOnTheTableJoinsItsBody) {
  // A neck whose support came out the table: its solid stands on the table through the body
  // (a rendered RealSense bottle's neck, r 18 mm, h 261 mm), yet its points start on the
  // shoulder, and that is where it rests.
  const ShapeEstimator estimator;
  BottleParts parts = fitBottleParts(estimator);
  Fitted& fitted = parts.fitted;
  const Plane& table = parts.table;
  ASSERT_EQ(fitted.fits.size(), 2u);
  ShapeFit& upper = fitted.fits[1];
  ASSERT_TRUE(upper.ok) << upper.reason;
  // The neck's solid stretched down to the table, as a fit on the table's support makes it.
  float& height = upper.type == ShapeType::Cube ? upper.dimensions.z() : upper.height;
  const float bottom = table.signedDistance(upper.center) - 0.5f * height;
  ASSERT_GT(bottom, 0.1f);
  upper.center -= 0.5f * bottom * table.normal.normalized();
  height += bottom;
  fitted.supports[1] = table;
  rejoinNecks(estimator, table, ViewBounds(), fitted.clusters, fitted.supports, fitted.fits);
  expectOneBottle(fitted, parts.body, parts.neck);
}

// A soup can standing on a box: the box below is no body, both stay.
TEST(RejoinNecks, CanOnABoxStaysApart) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const CloudPtr box = synthetic::box({0.15f, 0.10f, 0.05f}, {0.0f, 0.0f}, 0.0f, s);
  const CloudPtr can =
      synthetic::lifted(synthetic::roundObject(0.033f, 0.033f, 0.101f, {0.0f, 0.0f}, s), 0.05f);
  const ShapeEstimator estimator;
  Plane table;
  Fitted fitted = fitInCameraFrame({box, can}, s, estimator, table);
  ASSERT_EQ(fitted.fits.size(), 2u);
  rejoinNecks(estimator, table, ViewBounds(), fitted.clusters, fitted.supports, fitted.fits);
  ASSERT_EQ(fitted.fits.size(), 2u);
  EXPECT_EQ(fitted.fits[0].type, ShapeType::Cube);
  EXPECT_EQ(fitted.fits[1].type, ShapeType::Cylinder);
}

}  // namespace
}  // namespace tabletop_shapes
