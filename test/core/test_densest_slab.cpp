#include "tabletop_shapes/core/densest_slab.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

namespace tabletop_shapes {
namespace {

// The definition, as the table stage computed it before: all values sorted (-0 before +0), the
// first longest run [begin, end) with values[end - 1] <= values[begin] + width.
DensestSlab sortedRun(std::vector<float> values, float width) {
  std::sort(values.begin(), values.end(), [](float a, float b) {
    return a < b || (a == b && std::signbit(a) && !std::signbit(b));
  });
  size_t best_begin = 0, best_end = 0;
  for (size_t begin = 0, end = 0; begin < values.size(); ++begin) {
    while (end < values.size() && values[end] <= values[begin] + width) ++end;
    if (end - begin > best_end - best_begin) best_begin = begin, best_end = end;
  }
  if (best_end == 0) return {};
  return {best_end - best_begin, values[best_begin], values[best_end - 1]};
}

void expectSameFloat(float expected, float actual) {
  uint32_t a, b;
  std::memcpy(&a, &expected, sizeof a);
  std::memcpy(&b, &actual, sizeof b);
  EXPECT_EQ(a, b) << expected << " vs " << actual;
}

void expectAsSorted(const std::vector<float>& values, float width) {
  const DensestSlab expected = sortedRun(values, width);
  const DensestSlab slab = densestSlab(values, width);
  EXPECT_EQ(slab.count, expected.count);
  expectSameFloat(expected.low, slab.low);
  expectSameFloat(expected.high, slab.high);
}

TEST(DensestSlab, FindsTheMostValuesWithinTheWidth) {
  const DensestSlab slab = densestSlab({0.05f, 0.0f, 0.002f, -0.03f, 0.001f, 0.009f}, 0.008f);
  EXPECT_EQ(slab.count, 3u);
  EXPECT_EQ(slab.low, 0.0f);
  EXPECT_EQ(slab.high, 0.002f);
  // Two runs of three: the lower one.
  const DensestSlab tie = densestSlab({0.1f, 0.2f, 0.101f, 0.2005f, 0.102f, 0.201f}, 0.005f);
  EXPECT_EQ(tie.count, 3u);
  EXPECT_EQ(tie.low, 0.1f);
  EXPECT_EQ(tie.high, 0.102f);
  EXPECT_EQ(densestSlab({}, 0.008f).count, 0u);
  const DensestSlab one = densestSlab({0.25f}, 0.008f);
  EXPECT_EQ(one.count, 1u);
  EXPECT_EQ(one.low, 0.25f);
  EXPECT_EQ(one.high, 0.25f);
}

// Plane distances as the table stage sees them: a table surface (a narrow peak) among the
// lowest centimetres of objects' sides spread over the inlier band, on a grid of a few
// micrometres (many equal values), with -0 and +0.
TEST(DensestSlab, GivesTheSortedArraysRunOnTableLikeDistances) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    std::normal_distribution<float> surface(
        std::uniform_real_distribution<float>(-0.01f, 0.01f)(rng),
        std::uniform_real_distribution<float>(0.0005f, 0.004f)(rng));
    std::uniform_real_distribution<float> band(-0.015f, 0.015f);
    const int count = std::uniform_int_distribution<int>(1, 3000)(rng);
    const float spread_share = std::uniform_real_distribution<float>(0.0f, 1.0f)(rng);
    const float grid = trial % 3 == 0 ? 1e-5f : 0.0f;
    std::vector<float> values;
    for (int i = 0; i < count; ++i) {
      float v = std::uniform_real_distribution<float>(0.0f, 1.0f)(rng) < spread_share
                    ? band(rng)
                    : surface(rng);
      if (grid > 0.0f) v = std::round(v / grid) * grid;
      if (trial % 5 == 0 && i % 7 == 0) v = i % 2 ? 0.0f : -0.0f;
      values.push_back(v);
    }
    expectAsSorted(values, 0.008f);
    expectAsSorted(values, 0.0005f);
  }
}

TEST(DensestSlab, GivesTheSortedArraysRunOnSpreadAndNonFiniteValues) {
  // Spread far beyond the width (more bins than values): sorted outright.
  expectAsSorted({-1000.0f, 0.0f, 0.001f, 1000.0f, 1000.004f, 1000.005f}, 0.008f);
  // All equal; a width of zero.
  expectAsSorted(std::vector<float>(50, 0.003f), 0.008f);
  expectAsSorted({0.001f, 0.001f, 0.002f}, 0.0f);
  expectAsSorted({0.001f, std::numeric_limits<float>::infinity(), 0.002f, 0.0021f}, 0.008f);
}

}  // namespace
}  // namespace tabletop_shapes
