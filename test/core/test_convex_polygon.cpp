// The 2D convex hull (table hulls, footprints) against hulls known by construction, with the
// many inner points and collinear edge points that the extreme-point filter drops.
#include "tabletop_shapes/core/convex_polygon.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

using namespace tabletop_shapes;

namespace {

void expectHull(const std::vector<Eigen::Vector2f>& hull,
                const std::vector<Eigen::Vector2f>& expected) {
  ASSERT_EQ(hull.size(), expected.size());
  for (size_t i = 0; i < hull.size(); ++i) {
    EXPECT_EQ(hull[i], expected[i]) << "vertex " << i << ": " << hull[i].transpose();
  }
}

}  // namespace

TEST(ConvexHull2d, ASquareFullOfPointsIsItsFourCornersCounterClockwise) {
  std::vector<Eigen::Vector2f> points;
  // A 1.2 x 0.8 m table every 5 mm, edges included: the edge points are collinear.
  for (int i = 0; i <= 240; ++i) {
    for (int j = 0; j <= 160; ++j) points.emplace_back(0.3f + 0.005f * i, -0.4f + 0.005f * j);
  }
  const Eigen::Vector2f low_left = points.front(), high_right = points.back();
  const std::vector<Eigen::Vector2f> hull = convexHull2d(points);
  expectHull(
      hull, {low_left, {high_right.x(), low_left.y()}, high_right, {low_left.x(), high_right.y()}});
}

TEST(ConvexHull2d, ARandomDiscGetsItsRimPointsAndNothingInside) {
  std::mt19937 random(3);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<Eigen::Vector2f> points;
  // 64 points on a circle of 0.5 m, 20000 strictly inside it (radius <= 0.49 m).
  std::vector<Eigen::Vector2f> rim;
  for (int i = 0; i < 64; ++i) {
    const float angle = static_cast<float>(2.0 * M_PI * i / 64.0);
    rim.emplace_back(1.0f + 0.5f * std::cos(angle), 0.5f * std::sin(angle));
  }
  for (int i = 0; i < 20000; ++i) {
    const float angle = static_cast<float>(2.0 * M_PI) * unit(random);
    const float radius = 0.49f * std::sqrt(unit(random));
    points.emplace_back(1.0f + radius * std::cos(angle), radius * std::sin(angle));
  }
  points.insert(points.begin() + 7000, rim.begin(), rim.end());
  const std::vector<Eigen::Vector2f> hull = convexHull2d(points);
  // Counter-clockwise from the lowest x (the rim point at 180 deg).
  std::vector<Eigen::Vector2f> expected;
  for (int i = 0; i < 64; ++i) expected.push_back(rim[(32 + i) % 64]);
  expectHull(hull, expected);
  for (const Eigen::Vector2f& p : points) EXPECT_GE(insideDistance(hull, p), -1e-6f);
}

TEST(ConvexHull2d, DegenerateInputStaysDegenerate) {
  EXPECT_TRUE(convexHull2d({}).empty());
  std::vector<Eigen::Vector2f> line;
  for (int i = 0; i < 50; ++i) line.emplace_back(0.01f * i, 0.02f * i);
  const std::vector<Eigen::Vector2f> hull = convexHull2d(line);
  EXPECT_LT(hull.size(), 3u);
}

// The octagon of a diamond's and a square's points: points farther inside than the margin are
// surely inside, points within the margin of an edge, on it or outside are not; within() holds
// for hulls that contain the octagon (up to the tolerance) and fails for a smaller one.
TEST(ExtremeOctagon, SurelyInsideBeyondTheMarginAndWithinHullsHoldingIt) {
  // A square 0.4 m wide centred at (1, 0): its extreme points along the diagonals are its
  // corners, those along x and y the first points reaching them (corners too).
  const std::vector<Eigen::Vector2f> square = {
      {0.8f, -0.2f}, {1.2f, -0.2f}, {1.2f, 0.2f}, {0.8f, 0.2f}, {1.0f, 0.0f}};
  const float margin = 1e-3f;
  const ExtremeOctagon octagon(square, margin);
  EXPECT_TRUE(octagon.surelyInside({1.0f, 0.0f}));
  EXPECT_TRUE(octagon.surelyInside({1.19f, 0.19f}));
  EXPECT_FALSE(octagon.surelyInside({1.1995f, 0.0f}));  // within the margin of the edge x = 1.2
  EXPECT_FALSE(octagon.surelyInside({1.2f, 0.0f}));     // on it
  EXPECT_FALSE(octagon.surelyInside({1.3f, 0.0f}));
  EXPECT_FALSE(octagon.surelyInside({1.0f, -0.25f}));
  const std::vector<Eigen::Vector2f> hull = convexHull2d(square);
  EXPECT_TRUE(octagon.within(hull, 1e-6f));
  const std::vector<Eigen::Vector2f> larger = {
      {0.7f, -0.3f}, {1.3f, -0.3f}, {1.3f, 0.3f}, {0.7f, 0.3f}};
  EXPECT_TRUE(octagon.within(larger, 0.0f));
  const std::vector<Eigen::Vector2f> smaller = {
      {0.8f, -0.2f}, {1.19f, -0.2f}, {1.19f, 0.2f}, {0.8f, 0.2f}};
  EXPECT_FALSE(octagon.within(smaller, 1e-3f));  // its corners stand 1 cm outside
  EXPECT_TRUE(octagon.within(smaller, 0.02f));
  // Fewer than 3 distinct extreme points: nothing is surely inside, and any hull holds it.
  const ExtremeOctagon degenerate({{0.0f, 0.0f}, {1.0f, 1.0f}}, margin);
  EXPECT_FALSE(degenerate.surelyInside({0.5f, 0.5f}));
  EXPECT_TRUE(degenerate.within(hull, 0.0f));
  const ExtremeOctagon none({}, margin);
  EXPECT_FALSE(none.surelyInside({1.0f, 0.0f}));
}

// The octagon's corners are the first points reaching the extremes along x, x + y, y, y - x
// (and the opposite directions), found a lane's worth of points at a time: on points of a coarse
// grid (many ties) with NaNs among them, 1-40 of them (whole lanes and a rest), the octagon of
// all the points tests every probe as the octagon of the corners a plain loop finds, given in
// the points' order (so that each is still the first reaching its extreme). Run with and
// without TABLETOP_SHAPES_NO_AVX2.
TEST(ExtremeOctagon, CornersAreTheFirstPointsReachingTheExtremes) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> cell(-3, 3);
  const float margin = 1e-3f, nan = std::numeric_limits<float>::quiet_NaN();
  for (int trial = 0; trial < 300; ++trial) {
    const int n = 1 + trial % 40;
    std::vector<Eigen::Vector2f> points;
    for (int i = 0; i < n; ++i) {
      points.emplace_back(0.1f * cell(rng), 0.1f * cell(rng));
      if (cell(rng) == 3) points.back()[cell(rng) > 0 ? 0 : 1] = nan;
    }
    std::vector<int> first;  // the plain loop's corners, by index
    const float max = std::numeric_limits<float>::max();
    for (int d = 0; d < 8; ++d) {
      float best = d < 4 ? -max : max;
      int at = 0;
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector2f& p = points[i];
        const float along[4] = {p.x(), p.x() + p.y(), p.y(), p.y() - p.x()};
        if (d < 4 ? along[d] > best : along[d - 4] < best) best = along[d % 4], at = i;
      }
      first.push_back(at);
    }
    std::sort(first.begin(), first.end());
    first.erase(std::unique(first.begin(), first.end()), first.end());
    std::vector<Eigen::Vector2f> corners;
    for (int i : first) corners.push_back(points[i]);
    const ExtremeOctagon octagon(points, margin), expected(corners, margin);
    for (int i = -40; i <= 40; ++i) {
      for (int j = -40; j <= 40; ++j) {
        const Eigen::Vector2f probe(0.01f * i, 0.01f * j);
        ASSERT_EQ(octagon.surelyInside(probe), expected.surelyInside(probe))
            << "trial " << trial << ", probe " << probe.transpose();
      }
    }
  }
}

// keepNotSurelyInside keeps, in their order, the points that surelyInside does not call surely
// inside: 0-40 points of a disc (whole lanes and a rest) with NaNs among them, against the
// octagon of another draw. Run with and without TABLETOP_SHAPES_NO_AVX2.
TEST(ExtremeOctagon, KeepsThePointsNotSurelyInsideInTheirOrder) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
  auto draw = [&](int n) {
    std::vector<Eigen::Vector2f> points;
    for (int i = 0; i < n; ++i) {
      points.emplace_back(coordinate(rng), coordinate(rng));
      if (coordinate(rng) > 0.9f) points.back().x() = std::numeric_limits<float>::quiet_NaN();
    }
    return points;
  };
  for (int trial = 0; trial < 200; ++trial) {
    const ExtremeOctagon octagon(draw(3 + trial % 20), 0.01f);
    std::vector<Eigen::Vector2f> points = draw(trial % 41), expected;
    for (const Eigen::Vector2f& p : points) {
      if (!octagon.surelyInside(p)) expected.push_back(p);
    }
    EXPECT_EQ(octagon.keepNotSurelyInside(points), expected.size());
    ASSERT_EQ(points.size(), expected.size()) << "trial " << trial;
    for (size_t i = 0; i < points.size(); ++i) {
      EXPECT_EQ(std::memcmp(points[i].data(), expected[i].data(), sizeof(float) * 2), 0)
          << "trial " << trial << ", point " << i;
    }
  }
}

TEST(PolygonEdges, SameDistancesAsInsideDistanceAndInsideByItsThreshold) {
  // A hexagon with a repeated vertex (a zero-length edge, skipped by both), probed on a grid
  // reaching 0.3 m beyond it, and exactly on an edge's line.
  const std::vector<Eigen::Vector2f> hull = {{0.0f, 0.0f}, {0.4f, -0.1f}, {0.7f, 0.2f},
                                             {0.7f, 0.2f}, {0.5f, 0.6f},  {0.1f, 0.5f},
                                             {-0.2f, 0.3f}};
  const PolygonEdges edges(hull);
  int inside = 0, probes = 0;
  for (int i = -30; i <= 100; ++i) {
    for (int j = -40; j <= 90; ++j) {
      const Eigen::Vector2f q(0.01f * i, 0.01f * j);
      const float expected = insideDistance(hull, q);
      ASSERT_EQ(edges.insideDistance(q), expected) << q.transpose();  // bit for bit
      for (const float margin : {-0.05f, 0.0f, 0.02f, expected}) {
        ASSERT_EQ(edges.insideBy(q, margin), expected > margin) << q.transpose() << " " << margin;
      }
      inside += expected > 0.0f;
      ++probes;
    }
  }
  EXPECT_GT(inside, 1000);  // both sides probed
  EXPECT_GT(probes - inside, 1000);
  // The midpoint of the first edge: on it (to rounding), not inside by a micrometre.
  EXPECT_FALSE(edges.insideBy({0.2f, -0.05f}, 1e-6f));
  EXPECT_NEAR(edges.insideDistance({0.2f, -0.05f}), 0.0f, 1e-7f);
  // No vertices: nothing is outside, as insideDistance says (float max).
  const PolygonEdges none(std::vector<Eigen::Vector2f>{});
  EXPECT_EQ(none.insideDistance({1.0f, 1.0f}), insideDistance({}, {1.0f, 1.0f}));
  EXPECT_TRUE(none.insideBy({1.0f, 1.0f}, 1e30f));
}

TEST(SegmentMeetsPolygon, KnownCrossingsOfASquare) {
  const std::vector<Eigen::Vector2f> square = {
      {0.0f, 0.0f}, {1.0f, 0.0f}, {1.0f, 1.0f}, {0.0f, 1.0f}};
  using V = Eigen::Vector2f;
  EXPECT_TRUE(segmentMeetsPolygon(square, V(-1.0f, 0.5f), V(2.0f, 0.5f)));    // through it
  EXPECT_TRUE(segmentMeetsPolygon(square, V(0.5f, -2.0f), V(0.5f, 0.2f)));    // ends inside
  EXPECT_TRUE(segmentMeetsPolygon(square, V(0.2f, 0.2f), V(0.8f, 0.7f)));     // wholly inside
  EXPECT_TRUE(segmentMeetsPolygon(square, V(-1.0f, 1.0f), V(1.0f, -1.0f)));   // a corner
  EXPECT_FALSE(segmentMeetsPolygon(square, V(-1.0f, 0.5f), V(-0.1f, 0.5f)));  // stops short
  EXPECT_FALSE(segmentMeetsPolygon(square, V(-1.0f, 1.2f), V(2.0f, 1.2f)));   // passes above
  EXPECT_FALSE(segmentMeetsPolygon(square, V(-1.0f, 0.9f), V(0.2f, 2.0f)));   // cuts no corner
  EXPECT_FALSE(segmentMeetsPolygon(square, V(1.5f, -1.0f), V(1.5f, 2.0f)));   // parallel, beside
  EXPECT_FALSE(segmentMeetsPolygon({{0.0f, 0.0f}, {1.0f, 0.0f}}, V(0.5f, -1.0f), V(0.5f, 1.0f)));
}
