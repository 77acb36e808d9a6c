#include "tabletop_shapes/core/slab_nearest.h"

#include <gtest/gtest.h>
#include <pcl/kdtree/kdtree_flann.h>

#include <limits>
#include <random>

namespace tabletop_shapes {
namespace {

TEST(SlabNearest, FindsTheNearestPointWithinTheBound) {
  Cloud cloud;
  cloud.push_back(Point(0.0f, 0.0f, 1.0f));
  cloud.push_back(Point(0.1f, 0.0f, 1.0f));
  cloud.push_back(Point(-0.2f, 0.05f, 1.0f));
  const SlabNearest search(cloud);
  SlabNearest::Hit hit;
  ASSERT_TRUE(search.nearest(Eigen::Vector3f(0.07f, 0.0f, 1.0f), 1.0f, hit));
  EXPECT_EQ(hit.index, 1);
  EXPECT_NEAR(hit.squared, 0.0009f, 1e-7f);
  EXPECT_FALSE(hit.tied);
  // 3 cm away: within a bound of (3 cm)^2 + a little, not within (2.9 cm)^2.
  EXPECT_TRUE(search.nearest(Eigen::Vector3f(0.07f, 0.0f, 1.0f), 0.00091f, hit));
  EXPECT_FALSE(search.nearest(Eigen::Vector3f(0.07f, 0.0f, 1.0f), 0.00084f, hit));
}

TEST(SlabNearest, ReportsTiesWithTheFirstIndex) {
  Cloud cloud;
  cloud.push_back(Point(0.5f, 0.0f, 1.0f));
  cloud.push_back(Point(0.25f, 0.0f, 1.0f));
  cloud.push_back(Point(-0.25f, 0.0f, 1.0f));
  const SlabNearest search(cloud);
  SlabNearest::Hit hit;
  ASSERT_TRUE(search.nearest(Eigen::Vector3f(0.0f, 0.0f, 1.0f), 1.0f, hit));
  EXPECT_TRUE(hit.tied);
  EXPECT_EQ(hit.index, 1);
  EXPECT_EQ(hit.squared, 0.0625f);
}

// The same squared distance, to the bit, as pcl::KdTreeFLANN's nearest point, and the same
// point when it is the only one at that distance, on random clusters and queries around them
// (odd sizes: partial blocks), with bounds above and below the nearest distance.
TEST(SlabNearest, MatchesKdTreeFlann) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> coordinate(-0.1f, 0.1f);
  for (int size : {1, 5, 37, 1001}) {
    auto cloud = std::make_shared<Cloud>();
    for (int i = 0; i < size; ++i) {
      cloud->push_back(Point(coordinate(rng), coordinate(rng), 1.0f + coordinate(rng)));
    }
    const SlabNearest search(*cloud);
    pcl::KdTreeFLANN<Point> tree;
    tree.setInputCloud(cloud);
    std::vector<int> nearest(1);
    std::vector<float> squared(1);
    for (int query = 0; query < 200; ++query) {
      const Point q(3 * coordinate(rng), 3 * coordinate(rng), 1.0f + 3 * coordinate(rng));
      ASSERT_EQ(tree.nearestKSearch(q, 1, nearest, squared), 1);
      SlabNearest::Hit hit;
      ASSERT_TRUE(search.nearest(q.getVector3fMap(), std::numeric_limits<float>::max(), hit));
      EXPECT_EQ(hit.squared, squared[0]);
      EXPECT_FALSE(hit.tied);
      EXPECT_EQ(hit.index, nearest[0]);
      EXPECT_TRUE(search.nearest(q.getVector3fMap(), squared[0], hit));  // inclusive
      EXPECT_EQ(hit.index, nearest[0]);
      EXPECT_FALSE(search.nearest(q.getVector3fMap(), 0.999f * squared[0], hit));
    }
  }
}

}  // namespace
}  // namespace tabletop_shapes
