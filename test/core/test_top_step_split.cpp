// Splitting a level region at a step between two tops (issue 15): known answers on height grids.
#include "tabletop_shapes/core/top_step_split.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace tabletop_shapes {
namespace {

constexpr size_t kMinCells = 20;  // cluster_split's kMinTopCells

// A top of `width` x `depth` 1 cm cells from column `x0`, at `height` [m] plus `tilt` per
// column, each cell's height off by depth noise of `sigma` [m] (fixed seed).
void addTop(std::vector<HeightCell>& cells, int64_t x0, int64_t width, int64_t depth, float height,
            std::mt19937& rng, float sigma = 0.0015f, float tilt = 0.0f) {
  std::normal_distribution<float> noise(0.0f, sigma);
  for (int64_t x = x0; x < x0 + width; ++x) {
    for (int64_t y = 0; y < depth; ++y)
      cells.push_back({x, y, height + tilt * static_cast<float>(x - x0) + noise(rng)});
  }
}

// The group sizes, largest first.
std::vector<size_t> sizesOf(const std::vector<std::vector<int>>& groups) {
  std::vector<size_t> sizes;
  for (const auto& group : groups) sizes.push_back(group.size());
  std::sort(sizes.rbegin(), sizes.rend());
  return sizes;
}

TEST(TopStepSplit, TwoBoxTopsSixMillimetresApartSideBySideComeApart) {
  std::mt19937 rng(1);
  std::vector<HeightCell> cells;
  addTop(cells, 0, 10, 9, 0.100f, rng);
  addTop(cells, 10, 10, 9, 0.106f, rng);
  const auto groups = splitAtTopSteps(cells, kMinCells);
  ASSERT_EQ(groups.size(), 2u);
  // Each group is one box's top, up to a few cells along the step.
  for (const auto& group : groups) {
    const auto left =
        std::count_if(group.begin(), group.end(), [&](int i) { return cells[i].x < 10; });
    const size_t most = std::max<size_t>(left, group.size() - left);
    EXPECT_GE(most, 85u);
    EXPECT_LE(group.size() - most, 3u);
  }
}

TEST(TopStepSplit, ACanLidBesideABoxTopFiveMillimetresHigherComesApart) {
  // A lid 9 cm across (radius 4.5 cells) touching a 10 x 9 cell box top on its right.
  std::mt19937 rng(2);
  std::normal_distribution<float> noise(0.0f, 0.0015f);
  std::vector<HeightCell> cells;
  addTop(cells, 0, 10, 9, 0.100f, rng);
  size_t lid = 0;
  for (int64_t x = 10; x < 19; ++x) {
    for (int64_t y = 0; y < 9; ++y) {
      const float dx = x - 14.0f, dy = y - 4.0f;
      if (dx * dx + dy * dy > 4.5f * 4.5f) continue;
      cells.push_back({x, y, 0.105f + noise(rng)});
      ++lid;
    }
  }
  const auto groups = splitAtTopSteps(cells, kMinCells);
  ASSERT_EQ(groups.size(), 2u);
  EXPECT_EQ(sizesOf(groups), (std::vector<size_t>{90, lid}));
}

TEST(TopStepSplit, OneFlatNoisyTopStaysWhole) {
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    std::vector<HeightCell> cells;
    addTop(cells, 0, 20, 9, 0.100f, rng, 0.0025f);
    EXPECT_EQ(splitAtTopSteps(cells, kMinCells).size(), 1u) << "seed " << seed;
  }
}

TEST(TopStepSplit, ATiltedTopStaysWhole) {
  // 1 mm per centimetre: 2 cm from end to end, a plane.
  std::mt19937 rng(3);
  std::vector<HeightCell> cells;
  addTop(cells, 0, 20, 9, 0.100f, rng, 0.0015f, 0.001f);
  EXPECT_EQ(splitAtTopSteps(cells, kMinCells).size(), 1u);
}

TEST(TopStepSplit, ARimAroundALowerInsideStaysWhole) {
  // A 12 x 12 cell rim two cells wide at 0.100 m around an inside 5 mm lower.
  std::mt19937 rng(4);
  std::normal_distribution<float> noise(0.0f, 0.001f);
  std::vector<HeightCell> cells;
  for (int64_t x = 0; x < 12; ++x) {
    for (int64_t y = 0; y < 12; ++y) {
      const bool rim = x < 2 || y < 2 || x >= 10 || y >= 10;
      cells.push_back({x, y, (rim ? 0.100f : 0.095f) + noise(rng)});
    }
  }
  EXPECT_EQ(splitAtTopSteps(cells, kMinCells).size(), 1u);
}

TEST(TopStepSplit, AStepBelowThreeMillimetresOrATopTooSmallStaysWhole) {
  std::mt19937 rng(5);
  std::vector<HeightCell> low_step;
  addTop(low_step, 0, 10, 9, 0.100f, rng, 0.0005f);
  addTop(low_step, 10, 10, 9, 0.102f, rng, 0.0005f);
  EXPECT_EQ(splitAtTopSteps(low_step, kMinCells).size(), 1u);
  std::vector<HeightCell> small;  // 10 cells beside 90: under kMinCells
  addTop(small, 0, 10, 9, 0.100f, rng);
  addTop(small, 10, 2, 5, 0.110f, rng);
  EXPECT_EQ(splitAtTopSteps(small, kMinCells).size(), 1u);
}

}  // namespace
}  // namespace tabletop_shapes
