// The grid neighbour search against neighbours found by comparing every pair of points.
#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/types.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <random>

using namespace tabletop_shapes;

namespace {

// A noisy curved surface sampled every ~5 mm (as the core's voxel clouds), with a few sparse
// points around it and one NaN point.
CloudPtr surfaceCloud() {
  auto cloud = std::make_shared<Cloud>();
  std::mt19937 random(11);
  std::normal_distribution<float> noise(0.0f, 0.001f);
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 30; ++j) {
      const float x = -0.1f + 0.005f * i, y = 0.2f + 0.005f * j;
      cloud->push_back(Point(x, y, 1.0f + 2.0f * x * x + noise(random)));
    }
  }
  std::uniform_real_distribution<float> around(-0.15f, 0.15f);
  for (int i = 0; i < 30; ++i)
    cloud->push_back(Point(around(random), 0.27f + around(random), 1.1f));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud->push_back(Point(nan, nan, nan));
  cloud->is_dense = false;
  return cloud;
}

// Indices within `radius` of point i (squared distance < radius^2), nearest first, ties by index.
pcl::Indices bruteForce(const Cloud& cloud, size_t i, float radius) {
  std::vector<std::pair<float, int>> found;
  const Point& q = cloud[i];
  for (size_t j = 0; j < cloud.size(); ++j) {
    const float dx = cloud[j].x - q.x, dy = cloud[j].y - q.y, dz = cloud[j].z - q.z;
    const float d = dx * dx + dy * dy + dz * dz;
    if (d < radius * radius) found.emplace_back(d, static_cast<int>(j));
  }
  std::sort(found.begin(), found.end());
  pcl::Indices indices;
  for (const auto& f : found) indices.push_back(f.second);
  return indices;
}

}  // namespace

TEST(GridSearch, RadiusNeighboursOfEveryPointAreThoseOfAPairwiseSearch) {
  const CloudPtr cloud = surfaceCloud();
  for (const float radius : {0.02f, 0.012f}) {
    GridSearch<Point> search(0.02f);
    search.setInputCloud(cloud);
    std::vector<int> visits(cloud->size(), 0);
    size_t neighbours_seen = 0;
    search.forEachRadiusNeighbours(radius, [&](int i, const pcl::Indices& neighbours) {
      ++visits[i];
      neighbours_seen += neighbours.size();
      EXPECT_EQ(neighbours, bruteForce(*cloud, i, radius)) << "point " << i << ", r " << radius;
      pcl::Indices single;
      std::vector<float> squared;
      search.radiusSearch((*cloud)[i], radius, single, squared);
      EXPECT_EQ(neighbours, single) << "point " << i;
    });
    // Every finite point once, the NaN point never.
    for (size_t i = 0; i + 1 < cloud->size(); ++i) EXPECT_EQ(visits[i], 1) << i;
    EXPECT_EQ(visits.back(), 0);
    // A 2 cm disc on a 5 mm grid holds ~50 points: the test compares real neighbourhoods.
    EXPECT_GT(neighbours_seen, 20u * cloud->size() * radius / 0.02f);
  }
}

// Unsorted (as MLS asks for them), the lists hold the same neighbours, in some order, and on
// several threads the same order as in one pass.
TEST(GridSearch, UnsortedRadiusNeighboursAreThePairwiseSearchsSets) {
  const CloudPtr cloud = surfaceCloud();
  GridSearch<Point> search(0.02f, /*sorted=*/false);
  search.setInputCloud(cloud);
  std::vector<pcl::Indices> one_pass(cloud->size()), shared_out(cloud->size());
  size_t out_of_order = 0;
  search.forEachRadiusNeighbours(0.02, [&](int i, const pcl::Indices& neighbours) {
    one_pass[i] = neighbours;
    pcl::Indices sorted = neighbours;
    std::sort(sorted.begin(), sorted.end());
    pcl::Indices expected = bruteForce(*cloud, i, 0.02f);
    out_of_order += neighbours != expected;
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(sorted, expected) << "point " << i;
  });
  EXPECT_GT(out_of_order, 0u);  // the lists are not sorted by distance: that is the point
  search.forEachRadiusNeighbours(
      0.02, [&](int i, const pcl::Indices& neighbours) { shared_out[i] = neighbours; }, 2);
  EXPECT_EQ(shared_out, one_pass);
}

TEST(GridSearch, UnsortedNeighboursFollowTheIndicesOrderWhateverTheCellsSpanAndTheIndices) {
  // A search over only some indices lists a cell's points by index, whether the indices come
  // ascending or shuffled; the points span metres (hundreds of cells along each axis, a cell
  // order of several radix digits) and every list is the pairwise search's set.
  CloudPtr cloud = surfaceCloud();
  for (int i = 0; i < 40; ++i) {
    const float t = static_cast<float>(i);
    cloud->push_back(Point(-3.0f + 0.15f * t, 2.5f - 0.11f * t, 0.5f + 0.13f * t));
    cloud->push_back(Point(-3.0f + 0.15f * t + 0.004f, 2.5f - 0.11f * t, 0.5f + 0.13f * t));
  }
  pcl::Indices ascending;
  for (size_t i = 0; i < cloud->size(); i += 1 + i % 3) ascending.push_back(static_cast<int>(i));
  pcl::Indices shuffled = ascending;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(5));
  std::map<int, pcl::Indices> lists[2];
  for (int order = 0; order < 2; ++order) {
    GridSearch<Point> search(0.02f, /*sorted=*/false);
    search.setInputCloud(cloud,
                         std::make_shared<const pcl::Indices>(order == 0 ? ascending : shuffled));
    search.forEachRadiusNeighbours(
        0.02, [&](int i, const pcl::Indices& neighbours) { lists[order][i] = neighbours; });
  }
  ASSERT_EQ(lists[0].size(), ascending.size() - 1);  // the NaN point has no list
  EXPECT_EQ(lists[1], lists[0]);
  const std::set<int> chosen(ascending.begin(), ascending.end());
  for (const auto& [i, neighbours] : lists[0]) {
    pcl::Indices expected;
    for (const int j : bruteForce(*cloud, static_cast<size_t>(i), 0.02f))
      if (chosen.count(j)) expected.push_back(j);
    std::sort(expected.begin(), expected.end());
    pcl::Indices found = neighbours;
    std::sort(found.begin(), found.end());
    EXPECT_EQ(found, expected) << "point " << i;
  }
}

// Shared out among threads, the cells give every point the lists of one pass.
TEST(GridSearch, RadiusNeighboursOnSeveralThreadsAreThoseOfOnePass) {
  const CloudPtr cloud = surfaceCloud();
  GridSearch<Point> search(0.02f);
  search.setInputCloud(cloud);
  std::vector<pcl::Indices> one_pass(cloud->size()), shared_out(cloud->size());
  std::vector<int> visits(cloud->size(), 0);
  search.forEachRadiusNeighbours(
      0.02, [&](int i, const pcl::Indices& neighbours) { one_pass[i] = neighbours; });
  for (const unsigned threads : {2u, 3u}) {
    std::fill(visits.begin(), visits.end(), 0);
    search.forEachRadiusNeighbours(
        0.02,
        [&](int i, const pcl::Indices& neighbours) {
          shared_out[i] = neighbours;
          ++visits[i];  // each point on one thread only
        },
        threads);
    for (size_t i = 0; i + 1 < cloud->size(); ++i) {
      EXPECT_EQ(visits[i], 1) << i << ", " << threads << " threads";
      EXPECT_EQ(shared_out[i], one_pass[i]) << "point " << i << ", " << threads << " threads";
      EXPECT_GE(one_pass[i].size(), 1u);
    }
    EXPECT_EQ(visits.back(), 0);  // the NaN point
  }
}

TEST(GridSearch, NearestKIndicesOfEveryPointAreThoseOfAPairwiseSearch) {
  // 1 cm cells as predictShape uses them: the surface's points find their k nearest in the
  // block of cells around them, the sparse points around it fall back to the growing rings.
  const CloudPtr cloud = surfaceCloud();
  GridSearch<Point> search(0.01f);
  search.setInputCloud(cloud);
  for (const int k : {4, 30}) {
    std::vector<int> visits(cloud->size(), 0);
    search.forEachNearestKIndices(k, [&](int i, const pcl::Indices& nearest) {
      ++visits[i];
      pcl::Indices expected = bruteForce(*cloud, i, std::numeric_limits<float>::infinity());
      expected.resize(k);
      EXPECT_EQ(nearest, expected) << "point " << i << ", k " << k;
      ASSERT_FALSE(nearest.empty());
      EXPECT_EQ(nearest.front(), i);  // itself, at 0
      pcl::Indices single;
      std::vector<float> squared;
      search.nearestKSearch((*cloud)[i], k, single, squared);
      EXPECT_EQ(nearest, single) << "point " << i;
    });
    for (size_t i = 0; i + 1 < cloud->size(); ++i) EXPECT_EQ(visits[i], 1) << i;
    EXPECT_EQ(visits.back(), 0);
  }
}

TEST(GridSearch, NearestKIndicesOnSeveralThreadsAreThoseOfOnePass) {
  // The stack split's votes take the 16 nearest of every point of a pile on all free cores.
  const CloudPtr cloud = surfaceCloud();
  GridSearch<Point> search(0.01f);
  search.setInputCloud(cloud);
  std::vector<pcl::Indices> one_pass(cloud->size());
  search.forEachNearestKIndices(16,
                                [&](int i, const pcl::Indices& nearest) { one_pass[i] = nearest; });
  for (const unsigned threads : {2u, 3u}) {
    std::vector<pcl::Indices> shared_out(cloud->size());
    std::vector<int> visits(cloud->size(), 0);
    search.forEachNearestKIndices(
        16,
        [&](int i, const pcl::Indices& nearest) {
          ++visits[i];  // each point once, so no two threads write one entry
          shared_out[i] = nearest;
        },
        threads);
    for (size_t i = 0; i + 1 < cloud->size(); ++i) {
      EXPECT_EQ(visits[i], 1) << i << ", " << threads << " threads";
      EXPECT_EQ(shared_out[i], one_pass[i]) << "point " << i << ", " << threads << " threads";
      EXPECT_EQ(one_pass[i].size(), 16u);
    }
    EXPECT_EQ(visits.back(), 0);  // the NaN point
  }
}

namespace {

// The k smallest squared distances from point i to the cloud's finite points (itself
// included), ascending.
std::vector<float> nearestSquaredByPairs(const Cloud& cloud, size_t i, int k) {
  std::vector<float> squared;
  const Point& q = cloud[i];
  for (const Point& p : cloud.points) {
    const float dx = p.x - q.x, dy = p.y - q.y, dz = p.z - q.z;
    if (std::isfinite(dx)) squared.push_back(dx * dx + dy * dy + dz * dz);
  }
  std::sort(squared.begin(), squared.end());
  squared.resize(k);
  return squared;
}

// forEachNearestK on 2.5 cm cells (as the outlier removal), in no order, on `threads` threads:
// every point's k smallest squared distances those of nearestSquaredByPairs, each point once.
void expectNearestKDistancesByPairs(const CloudPtr& cloud, int k, unsigned threads) {
  GridSearch<Point> search(0.025f);
  search.setInputCloud(cloud);
  std::vector<int> visits(cloud->size(), 0);
  search.forEachNearestK(
      k,
      [&](int i, const std::vector<float>& squared) {
        ++visits[i];
        std::vector<float> found = squared;
        std::sort(found.begin(), found.end());
        EXPECT_EQ(found, nearestSquaredByPairs(*cloud, i, k))
            << "point " << i << " of " << cloud->size() << ", " << threads << " threads";
      },
      false, threads);
  for (size_t i = 0; i < cloud->size(); ++i) EXPECT_EQ(visits[i], 1) << i;
}

}  // namespace

TEST(GridSearch, NearestKDistancesOfEveryPointAreThoseOfAPairwiseSearch) {
  // 3 cm cells as the outlier removal uses them; ascending, and in any order (the same
  // multiset): the surface's points bound their selection by their cell neighbour's k-th
  // distance, the sparse points around it need the fallback search. On 3 threads (cells shared
  // out, visits concurrent) the same lists.
  const CloudPtr cloud = surfaceCloud();
  GridSearch<Point> search(0.03f);
  search.setInputCloud(cloud);
  constexpr int k = 51;
  for (const auto [ascending, threads] : {std::pair{true, 1u}, {false, 1u}, {true, 3u}}) {
    std::vector<int> visits(cloud->size(), 0);
    search.forEachNearestK(
        k,
        [&](int i, const std::vector<float>& squared) {
          ++visits[i];
          const std::vector<float> expected = nearestSquaredByPairs(*cloud, i, k);
          std::vector<float> found = squared;
          if (ascending) {
            EXPECT_TRUE(std::is_sorted(found.begin(), found.end())) << "point " << i;
          } else {
            std::sort(found.begin(), found.end());
          }
          EXPECT_EQ(found, expected)
              << "point " << i << (ascending ? ", ascending" : "") << ", " << threads << " threads";
        },
        ascending, threads);
    for (size_t i = 0; i + 1 < cloud->size(); ++i) EXPECT_EQ(visits[i], 1) << i;
    EXPECT_EQ(visits.back(), 0);
    // The points visited are the searched ones (the outlier removal's valid count).
    EXPECT_EQ(search.searchedPoints(), cloud->size() - 1);
  }
}

TEST(GridSearch, NearestKDistancesAmongEqualDistancesAreThoseOfAPairwiseSearch) {
  // A 5 mm lattice (voxel centres of a flat face) has few distinct distances, each shared by
  // 4-8 points: the k nearest cut through a ring of equal ones, and many of the candidates fall
  // into the selection's boundary bin. A stack of k + 4 copies of one point has its k nearest
  // all at 0 (the selection's bound is 0 there).
  auto cloud = std::make_shared<Cloud>();
  for (int i = 0; i < 30; ++i) {
    for (int j = 0; j < 30; ++j) cloud->push_back(Point(0.005f * i, 0.005f * j, 1.0f));
  }
  constexpr int k = 50;
  for (int copy = 0; copy < k + 4; ++copy) cloud->push_back(Point(0.5f, 0.5f, 1.0f));
  expectNearestKDistancesByPairs(cloud, k, 1);
}

TEST(GridSearch, NearestKDistancesOfIsolatedPointsAreThoseOfAPairwiseSearch) {
  // Points whose 3 x 3 x 3 block of cells holds fewer than k: a pair sharing a cell 40 cm
  // (16 cells) from a 5 mm lattice, a lone point 1 m away along a diagonal, three points a cell
  // apart beside the lattice's corner; their k nearest come from rings far beyond the block.
  // Then a cloud of k + 1 points spread over 60 cm: each point's k nearest are all but one.
  auto cloud = std::make_shared<Cloud>();
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) cloud->push_back(Point(0.005f * i, 0.005f * j, 1.0f));
  }
  for (const Point& p :
       {Point(0.5f, 0.05f, 1.0f), Point(0.503f, 0.052f, 1.001f), Point(-0.6f, -0.6f, 1.6f),
        Point(-0.03f, -0.03f, 1.0f), Point(-0.055f, -0.03f, 1.0f), Point(-0.08f, -0.03f, 1.02f)}) {
    cloud->push_back(p);
  }
  constexpr int k = 50;
  auto sparse = std::make_shared<Cloud>();
  for (int i = 0; i <= k; ++i) {
    sparse->push_back(Point(0.012f * static_cast<float>(i),
                            0.3f - 0.005f * static_cast<float>(i % 7),
                            1.0f + 0.001f * static_cast<float>(i % 3)));
  }
  for (const CloudPtr& points : {cloud, sparse}) {
    for (const unsigned threads : {1u, 2u}) expectNearestKDistancesByPairs(points, k, threads);
  }
}

TEST(GridSearch, ConnectedComponentsLinkAcrossTheBandBorderOverSeveralCells) {
  // A row of points 2.5 cm apart along x, linked at 3 cm on 1 cm cells: each link spans two or
  // three cells, the one across the two threads' border too. A lone point 4 cm beyond stays apart.
  Cloud row;
  for (int i = 0; i < 21; ++i) row.push_back(Point(0.025f * static_cast<float>(i), 0.3f, 1.0f));
  row.push_back(Point(0.54f, 0.3f, 1.0f));
  GridSearch<Point> search(0.01f, false);
  search.setInputCloud(std::make_shared<const Cloud>(row));
  pcl::Indices first_21(21);
  std::iota(first_21.begin(), first_21.end(), 0);
  const std::vector<pcl::Indices> expected{first_21, {21}};
  EXPECT_EQ(search.connectedComponents(0.03, 1), expected);
  EXPECT_EQ(search.connectedComponents(0.03, 2), expected);
}

TEST(GridSearch, ConnectedComponentsAreThoseOfAPairwiseUnion) {
  // Radii of one cell and of several (reach 1 and 3): each pair of points closer than the
  // radius links, whatever cells apart they lie.
  const CloudPtr cloud = surfaceCloud();
  const size_t finite_points = cloud->size() - 1;  // the last point is NaN
  // Cells of the radius (sub-cells 2 x 2 x 2), of a third (no sub-cells: a cell's points are
  // all closer than the radius), 1.67 radii (3 x 3 x 3 sub-cells), 2.5 radii (too large for
  // sub-cells: every pair in a cell tested).
  for (const auto& [cell, radius] : std::vector<std::pair<float, float>>{
           {0.006f, 0.006f}, {0.01f, 0.03f}, {0.01f, 0.006f}, {0.015f, 0.006f}}) {
    GridSearch<Point> search(cell, false);
    search.setInputCloud(cloud);
    // Reference: a union-find over every pair, components by smallest index.
    std::vector<size_t> parent(finite_points);
    std::iota(parent.begin(), parent.end(), 0);
    std::function<size_t(size_t)> root = [&](size_t i) {
      return parent[i] == i ? i : parent[i] = root(parent[i]);
    };
    for (size_t i = 0; i < finite_points; ++i) {
      for (size_t j = i + 1; j < finite_points; ++j) {
        const Point &p = (*cloud)[i], &q = (*cloud)[j];
        const float dx = q.x - p.x, dy = q.y - p.y, dz = q.z - p.z;
        if (dx * dx + dy * dy + dz * dz < radius * radius) {
          const size_t a = root(i), b = root(j);
          parent[std::max(a, b)] = std::min(a, b);
        }
      }
    }
    std::map<size_t, pcl::Indices> by_root;
    for (size_t i = 0; i < finite_points; ++i) by_root[root(i)].push_back(static_cast<int>(i));
    std::vector<pcl::Indices> expected;
    for (auto& [r, component] : by_root) expected.push_back(component);  // roots = smallest
    const std::vector<pcl::Indices> components = search.connectedComponents(radius);
    EXPECT_GT(components.size(), 1u) << "radius " << radius;  // the sparse points stay apart
    EXPECT_LT(components.size(), finite_points / 10) << "radius " << radius;  // the surface links
    EXPECT_EQ(components, expected) << "radius " << radius;
    // Two bands of cells linked at once, then their border: the same components.
    EXPECT_EQ(search.connectedComponents(radius, 2), expected) << "radius " << radius;
  }
}
