// The round-lid outline test on tops known by construction: the best circle through the outline
// points of a disc, and none where the radius bounds exclude it.
#include "tabletop_shapes/core/round_lid.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace tabletop_shapes;

namespace {

// A 10 cm box standing at the origin (its top at z = 0.1 m) and, on its top, a disc of radius
// `radius` centred at `center` (box frame): rings every 5 mm and 72 points on the rim.
struct DiscOnABox {
  ShapeFit box;
  Cloud cluster;
  DiscOnABox(const Eigen::Vector2f& center, float radius) {
    box.type = ShapeType::Cube;
    box.ok = true;
    box.center = Eigen::Vector3f(0.0f, 0.0f, 0.05f);
    box.dimensions = Eigen::Vector3f(0.1f, 0.1f, 0.1f);
    const float kPiF = static_cast<float>(M_PI);
    for (float r = 0.0f; r < radius; r += 0.005f) {
      for (int i = 0; i < 24; ++i) {
        const float angle = 2.0f * kPiF * (static_cast<float>(i) + 0.5f) / 24.0f;
        cluster.push_back(pcl::PointXYZ(center.x() + r * std::cos(angle),
                                        center.y() + r * std::sin(angle), 0.1f));
      }
    }
    for (int i = 0; i < 72; ++i) {
      const float angle = 2.0f * kPiF * static_cast<float>(i) / 72.0f;
      cluster.push_back(pcl::PointXYZ(center.x() + radius * std::cos(angle),
                                      center.y() + radius * std::sin(angle), 0.1f));
    }
  }
};

}  // namespace

TEST(TopOutline, ADiscsRimGivesItsCircleWithEveryOutlinePointOnIt) {
  const DiscOnABox top(Eigen::Vector2f(0.01f, -0.005f), 0.04f);
  const TopOutline outline = topOutline(top.box, top.cluster, 0.01f, 0.2f, 0.005f);
  ASSERT_GE(outline.points, 12);
  EXPECT_EQ(outline.on_circle, outline.points);
  EXPECT_NEAR(outline.radius, 0.04f, 1e-4f);
  EXPECT_NEAR(outline.center.x(), 0.01f, 1e-4f);
  EXPECT_NEAR(outline.center.y(), -0.005f, 1e-4f);
  EXPECT_GT(outline.arc_deg, 300.0f);
  EXPECT_EQ(outline.outside, 0.0f);
}

TEST(TopOutline, NoCircleWhereTheRadiusBoundsLeaveOutTheRim) {
  const DiscOnABox top(Eigen::Vector2f(0.0f, 0.0f), 0.04f);
  // Every circle through three rim points has the rim's radius, 4 cm.
  EXPECT_EQ(topOutline(top.box, top.cluster, 0.01f, 0.03f, 0.005f).points, 0);
  EXPECT_EQ(topOutline(top.box, top.cluster, 0.05f, 0.2f, 0.005f).points, 0);
}
