// Objects lying on others (beyond the paper): known answers for the plane each one rests on and
// the solid fitted on it. A box lying across two boxes comes apart into three, and the upper one
// gets its height from its own bottom face, not from the table under the pile.
#include "tabletop_shapes/core/support.h"

#include "tabletop_shapes/core/clustering.h"
#include "tabletop_shapes/core/shape_estimator.h"
#include "synthetic.h"

#include <gtest/gtest.h>

#include <algorithm>

namespace tabletop_shapes {
namespace {

float height(const Plane& table, const Eigen::Vector3f& p) { return table.signedDistance(p); }

// The points of a table-frame box above the line of sight from the sampler's camera over the
// edge at (y = edge_y, z = edge_z): what a box in front of it with that top back edge leaves.
CloudPtr aboveSightLine(const CloudPtr& cloud, const synthetic::Sampler& s, float edge_y,
                        float edge_z) {
  auto visible = std::make_shared<Cloud>();
  for (const auto& p : *cloud) {
    const float sight = edge_z - (p.y - edge_y) * (s.camera.z() - edge_z) / (edge_y - s.camera.y());
    if (p.z > sight) visible->push_back(p);
  }
  return visible;
}

TEST(Support, BoxAcrossTwoBoxesSplitsIntoThreeEachOnItsOwnBottom) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  // Two 10 x 10 x 8 cm boxes 6 cm apart; a 30 x 8 x 4 cm box lies across both.
  const float lower_height = 0.08f;
  const Eigen::Vector3f bridge_size(0.30f, 0.08f, 0.04f);
  const CloudPtr left = synthetic::withoutFootprint(
      synthetic::box({0.10f, 0.10f, lower_height}, {-0.08f, 0.0f}, 0.0f, s), -0.15f, 0.15f, -0.04f,
      0.04f, lower_height);
  const CloudPtr right = synthetic::withoutFootprint(
      synthetic::box({0.10f, 0.10f, lower_height}, {0.08f, 0.0f}, 0.0f, s), -0.15f, 0.15f, -0.04f,
      0.04f, lower_height);
  const CloudPtr bridge =
      synthetic::lifted(synthetic::box(bridge_size, {0.0f, 0.0f}, 0.0f, s), lower_height);
  auto scene = std::make_shared<Cloud>(*left);
  *scene += *right;
  *scene += *bridge;

  const Eigen::Isometry3f camera_from_table = synthetic::cameraFromTable(s);
  synthetic::transformCloud(camera_from_table, *scene);
  scene->width = static_cast<uint32_t>(scene->size());
  scene->height = 1;
  const Plane table = synthetic::transformPlane(camera_from_table, synthetic::tablePlane());

  std::vector<CloudPtr> clusters = extractClusters(scene, ClusteringParams(), &table);
  ASSERT_EQ(clusters.size(), 3u);
  const std::vector<Plane> supports = supportPlanes(clusters, table, Eigen::Vector3f::Zero());
  ASSERT_EQ(supports.size(), 3u);

  // The bridge is the cluster with the highest centroid.
  auto centroidHeight = [&](const CloudPtr& c) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (const auto& p : *c) sum += p.getVector3fMap();
    return height(table, sum / static_cast<float>(c->size()));
  };
  size_t upper = 0;
  for (size_t c = 1; c < clusters.size(); ++c) {
    if (centroidHeight(clusters[c]) > centroidHeight(clusters[upper])) upper = c;
  }
  for (size_t c = 0; c < clusters.size(); ++c) {
    const float lift = table.d - supports[c].d;  // same normal: the planes differ in d only
    EXPECT_NEAR(supports[c].normal.dot(table.normal), 1.0f, 1e-6f);
    EXPECT_NEAR(lift, c == upper ? lower_height : 0.0f, 0.005f) << "cluster " << c;
  }

  const ShapeEstimator estimator;
  const ShapeFit fit = estimator.estimate(clusters[upper], supports[upper]);
  ASSERT_TRUE(fit.ok) << fit.reason;
  EXPECT_EQ(fit.type, ShapeType::Cube);
  Eigen::Vector3f dims = fit.dimensions;
  std::sort(dims.data(), dims.data() + 3);
  EXPECT_NEAR(dims[0], bridge_size.z(), 0.005f);  // height from its own bottom: 4 cm, not 12
  EXPECT_NEAR(dims[1], bridge_size.y(), 0.01f);
  EXPECT_NEAR(dims[2], bridge_size.x(), 0.01f);
  EXPECT_NEAR(height(table, fit.center), lower_height + bridge_size.z() / 2, 0.005f);
  for (size_t c = 0; c < clusters.size(); ++c) {
    if (c == upper) continue;
    const ShapeFit lower = estimator.estimate(clusters[c], supports[c]);
    ASSERT_TRUE(lower.ok) << lower.reason;
    EXPECT_NEAR(height(table, lower.center), lower_height / 2, 0.005f);
  }
}

// A box whose lower part is hidden behind a box in front, 2 cm behind it, has nothing under it:
// it keeps the table. Its visible bottom (over the front box's top edge, seen from the sampler's
// camera at y = -0.8, z = 0.6) lies 1 cm below the front box's top, as a box lying on it would,
// so only the footprints tell them apart: the hidden box's points lie behind the front one's.
TEST(Support, BoxHiddenBehindAnotherKeepsTheTable) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const CloudPtr front = synthetic::box({0.15f, 0.05f, 0.18f}, {0.0f, -0.05f}, 0.0f, s);
  // Above the line of sight over the front box's top back edge (y = -0.025, z = 0.18).
  const CloudPtr visible_back = aboveSightLine(
      synthetic::box({0.12f, 0.06f, 0.25f}, {0.0f, 0.025f}, 0.0f, s), s, -0.025f, 0.18f);
  const std::vector<Plane> supports =
      supportPlanes({front, visible_back}, synthetic::tablePlane(), s.camera);
  ASSERT_EQ(supports.size(), 2u);
  EXPECT_FLOAT_EQ(supports[0].d, 0.0f);
  EXPECT_FLOAT_EQ(supports[1].d, 0.0f);
  // The same box lying on the front one (its bottom at the front box's top, over its footprint)
  // rests on it.
  const CloudPtr lying =
      synthetic::lifted(synthetic::box({0.12f, 0.05f, 0.04f}, {0.0f, -0.05f}, 0.0f, s), 0.18f);
  const std::vector<Plane> stacked =
      supportPlanes({front, lying}, synthetic::tablePlane(), s.camera);
  EXPECT_FLOAT_EQ(stacked[0].d, 0.0f);
  EXPECT_NEAR(-stacked[1].d, 0.18f, 0.003f);
}

// On a covered table objects stand 5-10 mm apart: the front face of a box 7 mm behind a lower
// one, above the line of sight over that one's top back edge, lies within kFootprintReach (1 cm)
// of its footprint, and its visible bottom just over that one's top, as for a box lying on it.
// Its bottom edge stands behind the front box as the camera sees it, and its centre 3.7 cm
// behind that box's footprint: the table is its support. (Rendered clutter of seed 2012: 11
// covered and 6 touching clusters like it were fitted as slabs on their front neighbour.)
TEST(Support, BoxJustBehindALowerOneKeepsTheTable) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const float front_height = 0.08f, gap = 0.007f;
  const CloudPtr front = synthetic::box({0.10f, 0.10f, front_height}, {0.0f, -0.05f}, 0.0f, s);
  const CloudPtr visible_back = aboveSightLine(
      synthetic::box({0.10f, 0.10f, 0.14f}, {0.0f, gap + 0.05f}, 0.0f, s), s, 0.0f, front_height);
  const size_t front_face = std::count_if(visible_back->begin(), visible_back->end(),
                                          [&](const auto& p) { return p.y < gap + 0.002f; });
  // Enough points on the front footprint's blurred edge to stand the box on the front one.
  ASSERT_GT(front_face, visible_back->size() / 5);
  const std::vector<Plane> supports =
      supportPlanes({front, visible_back}, synthetic::tablePlane(), s.camera);
  ASSERT_EQ(supports.size(), 2u);
  EXPECT_FLOAT_EQ(supports[0].d, 0.0f);
  EXPECT_FLOAT_EQ(supports[1].d, 0.0f);
}

// A tall box standing on a lower one whose top is seen only in front of it (OSD learn21: the
// footprint of the box beneath ends at the upper one's front face, as a front neighbour's does,
// and the upper's bottom edge lies on that edge, behind it as the camera sees it). The upper
// box's visible centre (its 14 cm front face and its top) lies 0.9 cm behind that edge, within
// kHiddenCentreOutside (1.5 cm): it rests there, lifted to the lower box's top.
TEST(Support, TallBoxOnABoxSeenOnlyInFrontOfItKeepsItsLift) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const float lower_height = 0.12f, upper_front = -0.02f;
  const CloudPtr whole_lower = synthetic::box({0.20f, 0.16f, lower_height}, {0.0f, 0.0f}, 0.0f, s);
  auto lower = std::make_shared<Cloud>();
  for (const auto& p : *whole_lower) {
    if (p.y < upper_front) lower->push_back(p);
  }
  const CloudPtr upper = synthetic::lifted(
      synthetic::box({0.12f, 0.06f, 0.14f}, {0.0f, upper_front + 0.03f}, 0.0f, s), lower_height);
  const std::vector<Plane> supports =
      supportPlanes({lower, upper}, synthetic::tablePlane(), s.camera);
  ASSERT_EQ(supports.size(), 2u);
  EXPECT_FLOAT_EQ(supports[0].d, 0.0f);
  EXPECT_NEAR(-supports[1].d, lower_height, 0.003f);
}

// The split cuts a pile at its concave seam, blurred upwards by noise: the box beneath keeps the
// upper box's lowest centimetre of side faces (rendered stacked clutter: bottoms 2-13 mm high).
// The top face of the box beneath, around the upper one, gives the real bottom: 6 cm, not 7.
TEST(Support, BoxOnABoxWhoseLowestRowsWentToTheBoxBeneathRestsOnItsTopFace) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const float lower_height = 0.06f, lost_rows = 0.01f;
  const Eigen::Vector3f upper_size(0.10f, 0.07f, 0.05f);
  const CloudPtr whole_upper =
      synthetic::lifted(synthetic::box(upper_size, {0.01f, 0.0f}, 0.0f, s), lower_height);
  auto lower = synthetic::withoutFootprint(
      synthetic::box({0.17f, 0.12f, lower_height}, {0.0f, 0.0f}, 0.0f, s), -0.04f, 0.06f, -0.035f,
      0.035f, lower_height);
  auto upper = std::make_shared<Cloud>();
  for (const auto& p : *whole_upper) {
    (p.z < lower_height + lost_rows ? *lower : *upper).push_back(p);
  }
  ASSERT_GT(upper->size(), 100u);
  const std::vector<Plane> supports =
      supportPlanes({lower, upper}, synthetic::tablePlane(), s.camera);
  ASSERT_EQ(supports.size(), 2u);
  EXPECT_FLOAT_EQ(supports[0].d, 0.0f);
  EXPECT_NEAR(-supports[1].d, lower_height, 0.002f);

  const ShapeFit fit = ShapeEstimator().estimate(upper, supports[1]);
  ASSERT_TRUE(fit.ok) << fit.reason;
  ASSERT_EQ(fit.type, ShapeType::Cube);
  Eigen::Vector3f dims = fit.dimensions;
  std::sort(dims.data(), dims.data() + 3);
  EXPECT_NEAR(dims[0], upper_size.z(), 0.005f);  // 5 cm, not 4
}

}  // namespace
}  // namespace tabletop_shapes
