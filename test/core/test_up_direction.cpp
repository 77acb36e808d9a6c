// "Up" in one syntax everywhere, the check of a given up against the scene, and the refusal of
// contradictory parameter pairs.
#include "tabletop_shapes/core/parameter_table.h"
#include "tabletop_shapes/core/up_direction.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <pcl/common/io.h>

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

using namespace tabletop_shapes;

TEST(ParseUp, AcceptsAutoAndBothVectorSyntaxes) {
  for (const char* text : {"auto", "", "  auto "}) {
    UpSetting up;
    up.automatic = false;
    std::string error;
    ASSERT_TRUE(parseUp(text, up, error)) << text << ": " << error;
    EXPECT_TRUE(up.automatic) << text;
  }
  for (const char* text : {"0,-0.8,-0.6", "[0, -0.8, -0.6]", " [ 0 ,-0.8,  -0.6 ] ", "0,-8,-6",
                           "[0.0, -8e-1, -0.6]"}) {
    UpSetting up;
    std::string error;
    ASSERT_TRUE(parseUp(text, up, error)) << text << ": " << error;
    EXPECT_FALSE(up.automatic) << text;
    EXPECT_NEAR(up.vector.x(), 0.0f, 1e-6f) << text;
    EXPECT_NEAR(up.vector.y(), -0.8f, 1e-6f) << text;
    EXPECT_NEAR(up.vector.z(), -0.6f, 1e-6f) << text;
  }
}

TEST(ParseUp, RefusesMalformedTextNamingIt) {
  for (const char* text : {"0,-1", "0,-1,0,0", "[0, -1, 0", "0, -1, 0]", "0 -1 0", "x,y,z", "0,0,0",
                           "nan,1,0", "inf,0,0", "[]", "[,,]", "up", "1,,2", "0,-1,0x"}) {
    UpSetting up;
    std::string error;
    EXPECT_FALSE(parseUp(text, up, error)) << text;
    EXPECT_EQ(error, std::string("up must be auto, X,Y,Z or [x, y, z] (a non-zero vector in "
                                 "the cloud frame), got '") +
                         text + "'");
  }
}

TEST(ParseUp, FormatRoundTrips) {
  EXPECT_EQ(formatUp(Eigen::Vector3f(0.0f, -0.766f, -0.643f)), "[0.000, -0.766, -0.643]");
  UpSetting up;
  std::string error;
  ASSERT_TRUE(parseUp(formatUp(Eigen::Vector3f(0.6f, 0.0f, -0.8f)), up, error)) << error;
  EXPECT_NEAR(up.vector.x(), 0.6f, 1e-6f);
  EXPECT_NEAR(up.vector.z(), -0.8f, 1e-6f);
}

TEST(ValidateParams, DefaultsAreConsistent) {
  std::string error;
  EXPECT_TRUE(validateParams(PipelineParams{}, error)) << error;
  EXPECT_TRUE(error.empty());
}

TEST(ValidateParams, ContradictoryPairsAreRefusedWithTheirValues) {
  PipelineParams params;
  params.shapes.predictor.section_low = 0.8f;
  params.shapes.predictor.section_high = 0.5f;
  params.shapes.cylinder.min_radius = 0.25f;
  params.shapes.cylinder.max_radius = 0.25f;
  params.clustering.min_size = 300;
  params.clustering.max_size = 200;
  params.table.min_height = 0.2f;
  params.table.max_height = 0.1f;
  std::string error;
  EXPECT_FALSE(validateParams(params, error));
  EXPECT_EQ(error,
            "predictor.section_low = 0.8 must be below predictor.section_high = 0.5; "
            "cylinder.min_radius = 0.25 must be below cylinder.max_radius = 0.25; "
            "clustering.min_size = 300 must be at most clustering.max_size = 200; "
            "table.min_height = 0.2 must be below table.max_height = 0.1");
  params = PipelineParams{};
  params.clustering.min_size = params.clustering.max_size = 500;  // one size only: fine
  EXPECT_TRUE(validateParams(params, error)) << error;
}

namespace {

// The paper's objects seen from 1 m, the camera pitched 40 deg down.
sim::RenderedScene tiltedScene() {
  return sim::renderScene(sim::paperScene({1.0f, 40.0f, 20.0f}, sim::NoiseModel(), 7));
}

float angleDeg(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0f, 1.0f)) * 180.0f /
         static_cast<float>(kPi);
}

CloudPtr xyz(const sim::RenderedScene& scene) {
  auto cloud = std::make_shared<Cloud>();
  pcl::copyPointCloud(*scene.cloud, *cloud);
  return cloud;
}

// The tilted scene's table segmented with `up` (the scene's true up when none is given).
struct SegmentedScene {
  sim::RenderedScene scene;
  CloudPtr cloud;
  TableParams params;
  TableResult table;
};

SegmentedScene segmentTiltedScene(const Eigen::Vector3f* up = nullptr) {
  SegmentedScene s;
  s.scene = tiltedScene();
  s.cloud = xyz(s.scene);
  s.params.up = up ? *up : s.scene.up;
  s.table = TableSegmenter(s.params).segment(s.cloud);
  return s;
}

}  // namespace

TEST(CheckUpAgainstScene, TheTrueUpPasses) {
  const SegmentedScene s = segmentTiltedScene();
  ASSERT_TRUE(s.table.found) << s.table.reason;
  const UpCheck check = checkUpAgainstScene(s.cloud, s.params, s.table);
  ASSERT_TRUE(check.scene_up_found);
  EXPECT_LT(check.up_angle_deg, 3.0f);
  EXPECT_LT(check.table_angle_deg, 3.0f);
  EXPECT_EQ(check.warning, "");
}

TEST(CheckUpAgainstScene, ATableHoldingMostPointsGivesTheScenesUpWithoutAPlaneSearch) {
  const SegmentedScene s = segmentTiltedScene();
  const CloudPtr& cloud = s.cloud;
  const TableParams& params = s.params;
  const TableResult& table = s.table;
  ASSERT_TRUE(table.found) << table.reason;
  size_t finite = 0;
  for (const auto& p : cloud->points) finite += p.getVector3fMap().allFinite();
  ASSERT_GT(2 * static_cast<size_t>(table.inliers), finite);  // the table is most of the view
  const UpCheck check = checkUpAgainstScene(cloud, params, table);
  EXPECT_TRUE(check.from_table);
  EXPECT_EQ(check.scene_up, table.plane.normal);
  Eigen::Vector3f searched;
  ASSERT_TRUE(estimateUp(cloud, params, searched));
  EXPECT_LT(angleDeg(check.scene_up, searched), 1.0f);  // what the plane search finds
  EXPECT_EQ(check.warning, "");

  // A wall filling as much of the view as the table: the table is no longer most of the
  // points, and the plane search decides (it still finds the table's up).
  auto walled = std::make_shared<Cloud>(*cloud);
  const size_t wall_points = finite;
  for (size_t i = 0; i < wall_points; ++i) {  // 5 mm grid, 2 m in front of the camera
    const float x = -1.0f + 0.005f * static_cast<float>(i % 400);
    const float y = -1.0f + 0.005f * static_cast<float>(i / 400 % 400);
    walled->push_back(Point(x, y, 2.0f + 0.005f * static_cast<float>(i / 160000)));
  }
  const UpCheck walled_check = checkUpAgainstScene(walled, params, table);
  EXPECT_FALSE(walled_check.from_table);
  ASSERT_TRUE(walled_check.scene_up_found);
  EXPECT_LT(angleDeg(walled_check.scene_up, s.scene.up), 3.0f);
  EXPECT_EQ(walled_check.warning, "");
}

TEST(CheckUpAgainstScene, TheLevelCameraGuessOnATiltedCameraIsWarnedWithItsAngle) {
  const Eigen::Vector3f level_camera_up(0.0f, -1.0f, 0.0f);  // the old default
  const SegmentedScene s = segmentTiltedScene(&level_camera_up);
  const sim::RenderedScene& scene = s.scene;
  const UpCheck check = checkUpAgainstScene(s.cloud, s.params, s.table);
  ASSERT_TRUE(check.scene_up_found);
  EXPECT_NEAR(check.up_angle_deg, 40.0f, 2.0f);
  EXPECT_LT((check.scene_up - scene.up).norm(), 0.05f) << check.scene_up.transpose();
  EXPECT_EQ(check.warning.rfind("up [0.000, -1.000, 0.000] is 40 deg from the scene's up [", 0), 0u)
      << check.warning;
  EXPECT_NE(check.warning.find("check up / up_frame"), std::string::npos) << check.warning;
  EXPECT_FALSE(check.from_table);
}

namespace {

sim::RenderedScene sceneAtPitch(float pitch_deg) {
  return sim::renderScene(sim::paperScene({1.0f, pitch_deg, 20.0f}, sim::NoiseModel(), 7));
}

}  // namespace

TEST(UpEstimate, HoldsTheUpForItsFramesThenEstimatesAgain) {
  const sim::RenderedScene first = sceneAtPitch(40.0f), turned = sceneAtPitch(45.0f);
  const CloudPtr first_cloud = xyz(first), turned_cloud = xyz(turned);
  UpEstimate estimate(3);
  TableParams params;
  TableResult table;
  ASSERT_TRUE(estimate.segment(first_cloud, params, table));
  ASSERT_TRUE(table.found) << table.reason;
  const Eigen::Vector3f held = params.up;
  EXPECT_LT(angleDeg(held, first.up), 2.0f);

  // The camera turned 5 deg, within up_tolerance_deg: frames 2 and 3 keep the held up and
  // still find the table.
  for (int frame = 2; frame <= 3; ++frame) {
    TableParams turned_params;
    ASSERT_TRUE(estimate.segment(turned_cloud, turned_params, table)) << frame;
    EXPECT_TRUE(table.found) << frame << ": " << table.reason;
    EXPECT_EQ(turned_params.up, held) << frame;
  }
  // Frame 4 estimates again and follows the camera.
  TableParams fourth;
  ASSERT_TRUE(estimate.segment(turned_cloud, fourth, table));
  EXPECT_TRUE(table.found) << table.reason;
  EXPECT_GT(angleDeg(fourth.up, held), 3.0f);
  EXPECT_LT(angleDeg(fourth.up, turned.up), 2.0f);
}

TEST(UpEstimate, EstimatesAtOnceWhenTheHeldUpFindsNoTable) {
  const sim::RenderedScene first = sceneAtPitch(40.0f), turned = sceneAtPitch(75.0f);
  UpEstimate estimate(30);
  TableParams params;
  TableResult table;
  ASSERT_TRUE(estimate.segment(xyz(first), params, table));
  ASSERT_TRUE(table.found) << table.reason;
  // 35 deg more down: the held up, beyond up_tolerance_deg, finds no table.
  TableParams held_params;
  held_params.up = params.up;
  EXPECT_FALSE(TableSegmenter(held_params).segment(xyz(turned)).found);
  TableParams turned_params;
  ASSERT_TRUE(estimate.segment(xyz(turned), turned_params, table));
  EXPECT_TRUE(table.found) << table.reason;
  EXPECT_LT(angleDeg(turned_params.up, turned.up), 2.0f);
}

TEST(UpEstimate, SaysWhyWithoutAPlaneToTakeUpFrom) {
  UpEstimate estimate;
  TableParams params;
  TableResult table;
  EXPECT_FALSE(estimate.segment(std::make_shared<Cloud>(), params, table));
  EXPECT_FALSE(table.found);
  EXPECT_EQ(table.reason, "no large plane with the camera above it to take 'up' from");
}
