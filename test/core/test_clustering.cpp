// §2.5 Euclidean cluster extraction: known objects apart / touching, size limits, bad input.
#include "tabletop_shapes/core/clustering.h"

#include "synthetic.h"

#include <gtest/gtest.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>

#include <limits>
#include <random>

namespace tabletop_shapes {
namespace {

synthetic::Sampler sampler() {
  synthetic::Sampler s;
  s.spacing = 0.004f;
  s.noise_sigma = 0.0005f;
  return s;
}

// A few isolated points (fewer than min_size), far from everything else.
Cloud specks() {
  Cloud cloud;
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> jitter(-0.003f, 0.003f);
  for (int i = 0; i < 40; ++i) cloud.push_back(Point(0.6f + jitter(rng), 0.6f + jitter(rng), 0.1f));
  return cloud;
}

TEST(Clustering, SeparatesObjectsAndSortsLargestFirst) {
  // A big box, a small box 6 cm to its right and a cylinder further away, plus specks.
  const CloudPtr big = synthetic::box({0.20f, 0.10f, 0.12f}, {0.0f, 0.0f}, 0.0f, sampler());
  const CloudPtr small = synthetic::box({0.06f, 0.06f, 0.05f}, {0.19f, 0.0f}, 0.0f, sampler());
  const CloudPtr can = synthetic::roundObject(0.035f, 0.035f, 0.11f, {-0.05f, 0.25f}, sampler());
  auto scene = std::make_shared<Cloud>();
  *scene += *small;  // not in size order on purpose
  *scene += *can;
  *scene += specks();
  *scene += *big;
  scene->header.frame_id = "camera";

  const std::vector<CloudPtr> clusters = extractClusters(scene, ClusteringParams());
  ASSERT_EQ(clusters.size(), 3u);
  std::vector<CloudPtr> expected = {big, small, can};
  std::sort(expected.begin(), expected.end(),
            [](const CloudPtr& a, const CloudPtr& b) { return a->size() > b->size(); });
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(clusters[i]->size(), expected[i]->size()) << "cluster " << i;
    EXPECT_EQ(clusters[i]->header.frame_id, "camera");
    EXPECT_EQ(clusters[i]->width, clusters[i]->size());
    EXPECT_EQ(clusters[i]->height, 1u);
    // Same centroid as the object it should be.
    Eigen::Vector3f a = Eigen::Vector3f::Zero(), b = Eigen::Vector3f::Zero();
    for (const auto& p : *clusters[i]) a += p.getVector3fMap();
    for (const auto& p : *expected[i]) b += p.getVector3fMap();
    EXPECT_LT((a / clusters[i]->size() - b / expected[i]->size()).norm(), 1e-4f);
  }
}

TEST(Clustering, SameClustersAsPclEuclideanClusterExtraction) {
  // Blobs of random points, some a little closer than the tolerance to each other, some a
  // little farther, plus lone points: PCL's extraction with a k-d tree is the reference.
  Cloud scene;
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int blob = 0; blob < 12; ++blob) {
    const Eigen::Vector3f centre(0.045f * blob, 0.02f * (blob % 3), 0.9f);
    const int size = 20 + 15 * (blob % 4);
    for (int i = 0; i < size; ++i) {
      const Eigen::Vector3f offset(0.02f * unit(rng), 0.02f * unit(rng), 0.02f * unit(rng));
      const Eigen::Vector3f p = centre + offset;
      scene.push_back(Point(p.x(), p.y(), p.z()));
    }
  }
  for (int i = 0; i < 30; ++i) scene.push_back(Point(unit(rng), unit(rng), 0.5f + unit(rng)));
  scene.is_dense = true;
  ClusteringParams params;
  params.tolerance = 0.01f;
  params.min_size = 3;
  params.max_size = 70;  // the largest blobs (65 points) stay; merged pairs of them do not
  const auto input = std::make_shared<const Cloud>(scene);

  std::vector<pcl::PointIndices> expected;
  pcl::EuclideanClusterExtraction<Point> extraction;
  extraction.setClusterTolerance(params.tolerance);
  extraction.setMinClusterSize(params.min_size);
  extraction.setMaxClusterSize(params.max_size);
  extraction.setSearchMethod(std::make_shared<pcl::search::KdTree<Point>>());
  extraction.setInputCloud(input);
  extraction.extract(expected);
  ASSERT_GE(expected.size(), 4u);  // the scene does test something

  const std::vector<CloudPtr> clusters = extractClusters(input, params);
  ASSERT_EQ(clusters.size(), expected.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    ASSERT_EQ(clusters[c]->size(), expected[c].indices.size()) << "cluster " << c;
    for (size_t i = 0; i < clusters[c]->size(); ++i) {
      EXPECT_EQ((*clusters[c])[i].getVector3fMap(), scene[expected[c].indices[i]].getVector3fMap())
          << "cluster " << c << " point " << i;
    }
  }
}

TEST(Clustering, ObjectsCloserThanTheToleranceMerge) {
  // 1.5 cm gap < d_th = 2 cm: one cluster; with d_th = 1 cm: two.
  const CloudPtr a = synthetic::box({0.06f, 0.06f, 0.05f}, {0.0f, 0.0f}, 0.0f, sampler());
  const CloudPtr b = synthetic::box({0.06f, 0.06f, 0.05f}, {0.075f, 0.0f}, 0.0f, sampler());
  auto scene = std::make_shared<Cloud>(*a);
  *scene += *b;
  EXPECT_EQ(extractClusters(scene, ClusteringParams()).size(), 1u);
  ClusteringParams fine;
  fine.tolerance = 0.01f;
  const std::vector<CloudPtr> clusters = extractClusters(scene, fine);
  ASSERT_EQ(clusters.size(), 2u);
  EXPECT_EQ(clusters[0]->size() + clusters[1]->size(), scene->size());
}

TEST(Clustering, SizeLimits) {
  const CloudPtr big = synthetic::box({0.20f, 0.10f, 0.12f}, {0.0f, 0.0f}, 0.0f, sampler());
  const CloudPtr small = synthetic::box({0.06f, 0.06f, 0.05f}, {0.3f, 0.0f}, 0.0f, sampler());
  auto scene = std::make_shared<Cloud>(*big);
  *scene += *small;
  ClusteringParams params;
  params.min_size = static_cast<int>(small->size()) + 1;  // the small box is too small
  std::vector<CloudPtr> clusters = extractClusters(scene, params);
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_EQ(clusters[0]->size(), big->size());
  params = ClusteringParams();
  params.max_size = static_cast<int>(big->size()) - 1;  // the big box is too big
  clusters = extractClusters(scene, params);
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_EQ(clusters[0]->size(), small->size());
}

TEST(Clustering, BadInputGivesNoClusters) {
  EXPECT_TRUE(extractClusters(CloudPtr(), ClusteringParams()).empty());
  EXPECT_TRUE(extractClusters(std::make_shared<Cloud>(), ClusteringParams()).empty());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  auto nans = std::make_shared<Cloud>(100, 10, Point(nan, nan, nan));
  nans->is_dense = false;
  EXPECT_TRUE(extractClusters(nans, ClusteringParams()).empty());
  // NaNs mixed into an object are skipped, not clustered.
  auto box = std::make_shared<Cloud>(
      *synthetic::box({0.06f, 0.06f, 0.05f}, {0.0f, 0.0f}, 0.0f, sampler()));
  const size_t box_size = box->size();
  box->push_back(Point(nan, 0.0f, 0.0f));
  box->is_dense = false;
  const std::vector<CloudPtr> clusters = extractClusters(box, ClusteringParams());
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_EQ(clusters[0]->size(), box_size);
  ClusteringParams zero;
  zero.tolerance = 0.0f;
  EXPECT_TRUE(extractClusters(box, zero).empty());
}

}  // namespace
}  // namespace tabletop_shapes
