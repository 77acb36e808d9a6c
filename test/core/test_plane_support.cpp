#include "tabletop_shapes/core/plane_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>

namespace tabletop_shapes {
namespace {

pcl::PointNormal pointWithNormal(const Eigen::Vector3f& position, const Eigen::Vector3f& normal) {
  pcl::PointNormal p;
  p.getVector3fMap() = position;
  p.getNormalVector3fMap() = normal;
  return p;
}

// The plane z = 0.5, thresholds 7 mm and 36 degrees (the box fit's defaults).
const Eigen::Vector3f kUp = Eigen::Vector3f::UnitZ();
constexpr float kDistance = 0.007f;
const float kCosThreshold = std::cos(static_cast<float>(kPi / 5));

TEST(PlaneSupport, KeepsThePointsNearThePlaneWhoseNormalsAgree) {
  NormalCloud cloud;
  const float tilts[] = {0.0f, 0.1f, 0.3f, 0.5f};  // radians, all within 36 degrees
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3f normal(std::sin(tilts[i]), 0.0f, std::cos(tilts[i]));
    cloud.push_back(pointWithNormal({0.1f * i, 0.0f, 0.5f + 0.002f * i}, normal));
  }
  cloud.push_back(pointWithNormal({0.0f, 0.1f, 0.52f}, kUp));                  // 2 cm above
  cloud.push_back(pointWithNormal({0.0f, 0.2f, 0.5f}, {0.866f, 0.0f, 0.5f}));  // 60 degrees
  cloud.push_back(pointWithNormal({0.0f, 0.3f, 0.499f}, -kUp));                // facing down
  const std::vector<int> indices = {6, 0, 1, 2, 3, 4, 5};

  PlaneSupport support(cloud, indices);
  std::vector<int> inliers;
  double angle_sum = 0.0;
  EXPECT_EQ(support.collect(kUp, -0.5f, kDistance, kCosThreshold, &inliers, &angle_sum), 5);
  EXPECT_EQ(inliers, (std::vector<int>{6, 0, 1, 2, 3}));
  EXPECT_NEAR(angle_sum, 0.9, 1e-5);  // the tilts; the downward normal is 0 off (either sign)
}

TEST(PlaneSupport, SumsNoAnglesBelowTheMinimumCount) {
  NormalCloud cloud;
  const Eigen::Vector3f tilted(0.0f, 0.5f, std::sqrt(0.75f));  // 30 degrees off the plane's
  for (int i = 0; i < 5; ++i) cloud.push_back(pointWithNormal({0.01f * i, 0.0f, 0.5f}, tilted));
  PlaneSupport support(cloud, {0, 1, 2, 3, 4});
  double angle_sum = 0.0;
  EXPECT_EQ(support.collect(kUp, -0.5f, kDistance, kCosThreshold, nullptr, &angle_sum, 6), 5);
  EXPECT_EQ(angle_sum, 0.0);
  EXPECT_EQ(support.collect(kUp, -0.5f, kDistance, kCosThreshold, nullptr, &angle_sum, 5), 5);
  EXPECT_NEAR(angle_sum, 5.0 * kPi / 6.0, 1e-5);
}

// Every float in [0.5, 1): the same bits as std::acos.
TEST(PlaneSupport, VectorAcosEqualsStdAcosOnEveryFloatFromHalfToOne) {
  const uint32_t first = 0x3f000000u, end = 0x3f800000u;  // 0.5, 1.0
  long differing = 0;
  for (uint32_t bits = first; bits < end; bits += 4) {
    Float4 x;
    for (uint32_t lane = 0; lane < 4; ++lane) {
      const uint32_t lane_bits = bits + lane;
      std::memcpy(&x[lane], &lane_bits, sizeof(float));
    }
    const Float4 angle = acosOfHalfToOne(x);
    for (int lane = 0; lane < 4; ++lane) {
      const float expected = std::acos(x[lane]);
      differing += std::memcmp(&angle[lane], &expected, sizeof(float)) != 0;
    }
  }
  EXPECT_EQ(differing, 0);
  const Float4 some = acosOfHalfToOne(Float4{0.5f, 0.75f, 0.9f, 0.99999994f});
  EXPECT_FLOAT_EQ(some[0], static_cast<float>(kPi / 3));
  EXPECT_NEAR(some[1], 0.722734248, 1e-7);
  EXPECT_NEAR(some[2], 0.451026812, 1e-7);
  EXPECT_NEAR(some[3], 3.4526698e-4, 1e-9);
}

// The same inliers and the same angle sum, to the bit, as the plain loop with Eigen's dot
// products, on a noisy box corner and tilted planes through it (odd sizes: partial blocks);
// with a cosine threshold below 0.5 too (angles the vector acos leaves to std::acos), and over
// 2^16 points (angles summed in the points' order), with and without the support collected.
void expectPlainLoopResults(float cos_threshold, int cloud_points = 1003, int trials = 50) {
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.003f);
  std::uniform_real_distribution<float> coordinate(-0.1f, 0.1f);
  NormalCloud cloud;
  for (int i = 0; i < cloud_points; ++i) {
    const int face = i % 3;
    Eigen::Vector3f position(coordinate(rng), coordinate(rng), coordinate(rng));
    position[face] = 0.1f + noise(rng);
    Eigen::Vector3f normal = Eigen::Vector3f::Unit(face);
    normal += Eigen::Vector3f(noise(rng), noise(rng), noise(rng)) * 100.0f;
    cloud.push_back(pointWithNormal(position, normal.normalized()));
  }
  std::vector<int> indices;
  for (int i = static_cast<int>(cloud.size()) - 1; i >= 0; i -= 2) indices.push_back(i);
  PlaneSupport support(cloud, indices);
  for (int trial = 0; trial < trials; ++trial) {
    const Eigen::Vector3f normal =
        (Eigen::Vector3f::Unit(trial % 3) +
         0.2f * Eigen::Vector3f(noise(rng), noise(rng), noise(rng)) / 0.003f)
            .normalized();
    const float d = -0.1f + noise(rng);
    std::vector<int> expected_inliers;
    double expected_sum = 0.0;
    for (int i : indices) {
      const auto& p = cloud[i];
      if (std::abs(normal.dot(p.getVector3fMap()) + d) >= kDistance) continue;
      const float cosine = std::abs(normal.dot(p.getNormalVector3fMap()));
      if (cosine <= cos_threshold) continue;
      expected_inliers.push_back(i);
      expected_sum += std::acos(std::min(cosine, 1.0f));
    }
    std::vector<int> inliers;
    double angle_sum = 0.0;
    const int count = support.collect(normal, d, kDistance, cos_threshold, &inliers, &angle_sum);
    EXPECT_EQ(count, static_cast<int>(expected_inliers.size()));
    EXPECT_EQ(inliers, expected_inliers);
    EXPECT_EQ(angle_sum, expected_sum);
    double angles_only = 0.0;
    EXPECT_EQ(support.collect(normal, d, kDistance, cos_threshold, nullptr, &angles_only), count);
    EXPECT_EQ(angles_only, expected_sum);
    if (cos_threshold < 0.5f) continue;  // the bound holds for the inliers' cosines in [0.5, 1]
    double bound = -1.0;
    EXPECT_EQ(support.countWithAngleBound(normal, d, kDistance, cos_threshold, bound), count);
    EXPECT_LE(bound, expected_sum);
    EXPECT_GE(bound, 0.98 * expected_sum);  // angles up to the 36-degree threshold: >= 0.984
  }
}

TEST(PlaneSupport, MatchesThePlainLoopBitForBit) { expectPlainLoopResults(kCosThreshold); }

TEST(PlaneSupport, MatchesThePlainLoopBitForBitWithWideAngles) {
  expectPlainLoopResults(std::cos(static_cast<float>(kPi * 0.45)));  // 81 degrees
}

TEST(PlaneSupport, MatchesThePlainLoopBitForBitOnManyPoints) {
  expectPlainLoopResults(kCosThreshold, 140001, 4);  // every second: 70001 points
}

// Where the root and the acos agree to the float (cosines next to 1: 0.99999994 gives
// 3.4526698e-4 both ways), and for cosines rounded above 1 (angle 0), the bound stays at or
// below the angles' sum; at 30 degrees it lies within 1.2 % of it.
TEST(PlaneSupport, AngleBoundStaysBelowTheSumOfTheAngles) {
  const float next_to_one = std::nextafter(1.0f, 0.0f);
  const Eigen::Vector3f tilted(0.0f, std::sqrt(1.0f - next_to_one * next_to_one), next_to_one);
  for (const Eigen::Vector3f& normal :
       {tilted, Eigen::Vector3f(0.0f, 0.5f, std::sqrt(0.75f)), Eigen::Vector3f(kUp)}) {
    NormalCloud cloud;
    for (int i = 0; i < 4001; ++i) {
      cloud.push_back(pointWithNormal({0.0001f * i, 0.0f, 0.5f}, normal));
    }
    std::vector<int> indices(cloud.size());
    for (size_t i = 0; i < indices.size(); ++i) indices[i] = static_cast<int>(i);
    PlaneSupport support(cloud, indices);
    double sum = 0.0, bound = -1.0;
    ASSERT_EQ(support.collect(kUp, -0.5f, kDistance, kCosThreshold, nullptr, &sum), 4001);
    ASSERT_EQ(support.countWithAngleBound(kUp, -0.5f, kDistance, kCosThreshold, bound), 4001);
    EXPECT_LE(bound, sum);
    EXPECT_GE(bound, 0.988 * sum);
  }
}

// The points are counted a lane's worth at a time (eight where the CPU has AVX2): every count
// of points, whole lanes or not, gives every inlier once and none of the padding, and a bound
// at or below the sum of the angles.
TEST(PlaneSupport, CountsEveryPointOnceWhateverTheLanesLeftOver) {
  const Eigen::Vector3f tilted = Eigen::Vector3f(0.0f, 0.3f, 1.0f).normalized();
  for (int n = 1; n <= 24; ++n) {
    NormalCloud cloud;
    for (int i = 0; i < n; ++i) {
      // Every third point 2 cm off the plane: not an inlier.
      const float height = i % 3 == 2 ? 0.52f : 0.5f;
      cloud.push_back(pointWithNormal({0.001f * i, 0.0f, height}, tilted));
    }
    std::vector<int> indices(cloud.size());
    for (size_t i = 0; i < indices.size(); ++i) indices[i] = static_cast<int>(i);
    PlaneSupport support(cloud, indices);
    double sum = 0.0, bound = -1.0;
    const int expected = n - n / 3;
    ASSERT_EQ(support.collect(kUp, -0.5f, kDistance, kCosThreshold, nullptr, &sum), expected);
    EXPECT_EQ(support.countWithAngleBound(kUp, -0.5f, kDistance, kCosThreshold, bound), expected)
        << n << " points";
    EXPECT_LE(bound, sum);
    EXPECT_GE(bound, 0.99 * sum);
  }
}

TEST(PointsNearPlane, KeepsThePointsWithinTheDistanceInTheOrderGiven) {
  Cloud cloud;
  for (int i = 0; i < 7; ++i) cloud.push_back(Point(0.1f * i, 0.0f, 0.5f + 0.003f * i));
  cloud.push_back(Point(0.0f, 0.0f, std::numeric_limits<float>::quiet_NaN()));
  const PointsNearPlane points(cloud, {7, 6, 0, 2, 1, 4});
  Plane plane;
  plane.normal = kUp;
  plane.d = -0.5f;  // z = 0.5: point i lies 3 i mm above it
  std::vector<int> within = {99};
  points.collect(plane, kDistance, within);
  EXPECT_EQ(within, (std::vector<int>{0, 2, 1}));
  plane.d = -0.512f;  // z = 12 mm higher
  points.collect(plane, 0.0035f, within);
  EXPECT_EQ(within, (std::vector<int>{4}));
}

// Plane::signedDistance is Eigen's dot (x0 y0 + (x1 y1 + x2 y2)) + d: points on the edge of the
// band fall on the side that order of float operations puts them, in both.
TEST(PointsNearPlane, MatchesThePlainLoopBitForBit) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
  Cloud cloud;
  for (int i = 0; i < 5003; ++i) {
    cloud.push_back(Point(coordinate(rng), coordinate(rng), 1.0f + coordinate(rng)));
  }
  std::vector<int> indices;
  for (int i = 0; i < 5003; i += 1 + i % 3) indices.push_back(i);
  const PointsNearPlane points(cloud, indices);
  for (int trial = 0; trial < 50; ++trial) {
    Plane plane;
    plane.normal = Eigen::Vector3f(coordinate(rng), coordinate(rng), coordinate(rng)).normalized();
    plane.d = coordinate(rng);
    const float threshold = trial % 2 ? 0.015f : 0.004f;
    std::vector<int> expected, within;
    for (const int i : indices) {
      if (std::abs(plane.signedDistance(cloud[i].getVector3fMap())) <= threshold) {
        expected.push_back(i);
      }
    }
    points.collect(plane, threshold, within);
    EXPECT_EQ(within, expected);
    // Thresholds on a point's own distance: the edge case of <=.
    const float edge = std::abs(plane.signedDistance(cloud[indices[trial]].getVector3fMap()));
    points.collect(plane, edge, within);
    EXPECT_NE(std::find(within.begin(), within.end(), indices[trial]), within.end());
  }
}

}  // namespace
}  // namespace tabletop_shapes
