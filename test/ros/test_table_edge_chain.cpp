// The table-edge rule in the ROS chain (issue 12): TableSegmentation's Table message carries the
// table's depth noise, hull_margin and viewpoint through ROS serialisation, and
// ShapeEstimation's step (bridge::rejectClustersOffTheTable) rejects, from that message, the
// very clusters the core Pipeline rejects, with the same reasons. Without a master.
#include "tabletop_shapes/core/clustering.h"
#include "tabletop_shapes/core/pipeline.h"
#include "tabletop_shapes/ros/conversions.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <gtest/gtest.h>

#include "message_round_trip.h"

#include <vector>

namespace tabletop_shapes {
namespace {

using tabletop_shapes_test::roundTrip;

TEST(TableEdgeChain, TableMessageCarriesWhatTheRuleNeeds) {
  TableResult table;
  table.found = true;
  table.inliers = 5000;
  table.plane = Plane{Eigen::Vector3f(0.0f, -0.8f, -0.6f), 0.9f};
  table.hull = {{0.1f, 0.2f, 1.0f}, {0.4f, 0.2f, 1.1f}, {0.3f, 0.5f, 1.3f}};
  table.depth_noise_at_one_metre = 0.0037f;
  std_msgs::Header header;
  header.frame_id = "camera_depth_optical_frame";
  const Table msg =
      roundTrip(bridge::toTableMsg(table, 0.03f, Eigen::Vector3f(0.01f, -0.02f, 0.05f), header));
  EXPECT_FLOAT_EQ(msg.depth_noise_at_one_metre, 0.0037f);
  EXPECT_FLOAT_EQ(msg.hull_margin, 0.03f);
  EXPECT_NEAR(msg.viewpoint.x, 0.01, 1e-7);
  EXPECT_NEAR(msg.viewpoint.y, -0.02, 1e-7);
  EXPECT_NEAR(msg.viewpoint.z, 0.05, 1e-7);
  const std::vector<Eigen::Vector3f> hull = bridge::hullFromMsg(msg);
  ASSERT_EQ(hull.size(), table.hull.size());
  for (size_t i = 0; i < hull.size(); ++i) EXPECT_TRUE(hull[i].isApprox(table.hull[i]));

  // A frame without a table carries none of it.
  const Table none = bridge::toTableMsg(TableResult(), 0.03f, Eigen::Vector3f::Ones(), header);
  EXPECT_FALSE(bridge::tableFound(none));
  EXPECT_EQ(none.hull_margin, 0.0f);
}

TEST(TableEdgeChain, TransformMovesTheViewpointAndTheRejectedClusters) {
  Objects objects;
  objects.table.inliers = 100;
  objects.table.coefficients = {0.0, 0.0, 1.0, 0.0};
  objects.table.viewpoint.x = 1.0;
  UnfittedCluster rejected;
  rejected.centroid.y = 2.0;
  objects.rejected.push_back(rejected);
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(0.5, 0.0, -1.0);
  bridge::transformObjects(shift, "base_link", objects);
  EXPECT_DOUBLE_EQ(objects.table.viewpoint.x, 1.5);
  EXPECT_DOUBLE_EQ(objects.table.viewpoint.z, -1.0);
  EXPECT_DOUBLE_EQ(objects.rejected[0].centroid.x, 0.5);
  EXPECT_DOUBLE_EQ(objects.rejected[0].centroid.y, 2.0);
}

// The RealSense everyday scene whose table stands 12.6 cm before a wall (test_table_edge's
// RenderedWallBehindTheTableGivesNoObjects): the chain's path, from the serialised Table and
// View messages and the clusters as Clustering publishes them (no sensor origin: the cloud
// passed a topic), rejects what Pipeline rejects.
TEST(TableEdgeChain, RenderedWallFootIsRejectedAsInThePipeline) {
  const sim::RenderedScene scene =
      sim::renderScene(sim::everydayScene(1623110328u, sim::SensorModel::RealSenseD435));
  ASSERT_TRUE(scene.spec.table.back_wall);
  PipelineParams params;
  params.table.up = scene.up;
  const SceneResult pipeline = Pipeline(params).process(*scene.cloud);
  ASSERT_TRUE(pipeline.table.found) << pipeline.table.reason;
  ASSERT_GE(pipeline.rejected.size(), 1u) << "the scene's wall foot gives a cluster";

  std::vector<CloudPtr> clusters =
      extractClusters(pipeline.table.object_points, params.clustering, &pipeline.table.plane);
  for (CloudPtr& cluster : clusters) cluster->sensor_origin_.setZero();
  const size_t extracted = clusters.size();
  const Eigen::Vector3f eye = pipeline.table.object_points->sensor_origin_.head<3>();
  std_msgs::Header header;
  const Table table =
      roundTrip(bridge::toTableMsg(pipeline.table, params.table.hull_margin, eye, header));
  const ViewBounds view = bridge::viewFromMsg(roundTrip(bridge::toViewMsg(pipeline.view, header)));
  Objects objects;
  bridge::rejectClustersOffTheTable(table, &view, clusters, objects);

  // (Pipeline's own clusters are joined further after fitting: bottle necks.)
  EXPECT_EQ(clusters.size() + objects.rejected.size(), extracted) << "each kept or rejected";
  ASSERT_EQ(objects.rejected.size(), pipeline.rejected.size());
  for (size_t i = 0; i < objects.rejected.size(); ++i) {
    const UnfittedCluster expected = bridge::toRejectedMsg(pipeline.rejected[i]);
    EXPECT_EQ(objects.rejected[i].points, expected.points);
    EXPECT_NEAR(objects.rejected[i].centroid.x, expected.centroid.x, 1e-6);
    EXPECT_NEAR(objects.rejected[i].centroid.z, expected.centroid.z, 1e-6);
    EXPECT_EQ(objects.rejected[i].reason, expected.reason);
    EXPECT_NE(objects.rejected[i].reason.find("not on the table"), std::string::npos);
  }

  // Without the fields (an older TableSegmentation: zeros) the band is hull_margin 0 and no
  // noise: the slab, 2-6 cm over the hull, is then kept, so the fields matter.
  Table bare = table;
  bare.depth_noise_at_one_metre = 0.0f;
  bare.hull_margin = 0.0f;
  std::vector<CloudPtr> again =
      extractClusters(pipeline.table.object_points, params.clustering, &pipeline.table.plane);
  Objects without;
  bridge::rejectClustersOffTheTable(bare, &view, again, without);
  EXPECT_LT(without.rejected.size(), objects.rejected.size());
}

}  // namespace
}  // namespace tabletop_shapes
