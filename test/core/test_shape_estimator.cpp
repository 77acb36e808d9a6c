#include "tabletop_shapes/core/shape_estimator.h"

#include "tabletop_shapes/core/cube_fit.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <initializer_list>
#include <limits>
#include <map>
#include <random>
#include <string>

#include "synthetic.h"

namespace tabletop_shapes {
namespace {

const Eigen::Vector3f kMilkTea(0.15f, 0.095f, 0.05f);  // the paper's flat box

// Flying pixels of a Kinect at the box's hidden top edges, where the top face ends against the
// table far behind: the sensor returns depths in between (the scene renderer gives 30 % of the
// pixels at such a jump a depth drawn uniformly between both sides). Per `spacing` of edge,
// `per_sample` points along the ray behind the edge, kept from 8 mm above the table like the
// table segmentation keeps them.
void addFlyingPixels(const Eigen::Vector3f& size, float yaw, const synthetic::Sampler& s,
                     int per_sample, Cloud& cloud) {
  std::mt19937 rng(s.seed + 1);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  for (int axis = 0; axis < 2; ++axis) {
    for (int sign : {-1, 1}) {
      Eigen::Vector3f outward = Eigen::Vector3f::Zero();
      outward[axis] = static_cast<float>(sign);
      const Eigen::Vector3f middle(outward.x() * size.x() / 2, outward.y() * size.y() / 2,
                                   size.z());
      if ((R * outward).dot(s.camera - R * middle) > 0.0f) continue;  // the side face is seen
      const int along = 1 - axis;
      for (float a = -size[along] / 2; a <= size[along] / 2 + 1e-6f; a += s.spacing) {
        Eigen::Vector3f local = middle;
        local[along] = a;
        const Eigen::Vector3f edge = R * local;
        const float t_table = s.camera.z() / (s.camera.z() - edge.z());  // ray meets z = 0
        for (int k = 0; k < per_sample; ++k) {
          const float t = 1.0f + uniform(rng) * (t_table - 1.0f);
          const Eigen::Vector3f p = s.camera + t * (edge - s.camera);
          if (p.z() >= 0.008f) cloud.push_back(Point(p.x(), p.y(), p.z()));
        }
      }
    }
  }
  cloud.width = static_cast<uint32_t>(cloud.size());
  cloud.height = 1;
}

TEST(ShapeEstimator, FlatBoxWithFlyingPixelsAtOneMetreIsABox) {
  // The milk-tea box lying flat 1.1 m from the camera, 38 degrees below it, sampled at the
  // voxel grid's 5 mm. Noise: the Kinect's axial sigma there (2.1 mm, scene renderer) averaged
  // over the ~4 pixels of a voxel. Flying pixels behind its far top edges made ~5 % of such
  // clusters in the rendered benchmark, up to 10 cm off the box: its fit's plain rmse rose to
  // 5-10 mm, above the 2-4 mm of a cylinder r 9-10 cm through its side faces, and the box
  // was taken for that cylinder.
  synthetic::Sampler sampler;
  sampler.camera = Eigen::Vector3f(0.0f, -0.85f, 0.7f);
  sampler.spacing = 0.005f;
  sampler.noise_sigma = 0.00105f;
  int boxes = 0;
  const float yaws[] = {0.0f, 0.4f, 0.8f, 1.2f, 1.6f, 2.0f, 2.4f, 2.8f};
  for (float yaw : yaws) {
    for (unsigned seed : {1u, 2u}) {
      sampler.seed = seed;
      CloudPtr cloud = synthetic::box(kMilkTea, {0.0f, 0.0f}, yaw, sampler);
      const size_t surface_points = cloud->size();
      addFlyingPixels(kMilkTea, yaw, sampler, 2, *cloud);
      // Camera at the origin: MLS orients the normals towards it.
      const Eigen::Isometry3f to_camera(Eigen::Translation3f(-sampler.camera));
      synthetic::transformCloud(to_camera, *cloud);
      const Plane table = synthetic::transformPlane(to_camera, synthetic::tablePlane());

      const ShapeFit fit = ShapeEstimator().estimate(cloud, table);
      std::printf("yaw %.1f seed %u: %zu + %zu flying points -> %s %.3f x %.3f x %.3f r %.3f\n",
                  yaw, seed, surface_points, cloud->size() - surface_points,
                  shapeTypeName(fit.type), fit.dimensions.x(), fit.dimensions.y(),
                  fit.dimensions.z(), fit.radius);
      EXPECT_TRUE(fit.ok) << fit.reason;
      EXPECT_EQ(fit.type, ShapeType::Cube) << "yaw " << yaw << " seed " << seed;
      if (fit.type != ShapeType::Cube) continue;
      ++boxes;
      EXPECT_NEAR(fit.dimensions.x(), kMilkTea.x(), 0.05f * kMilkTea.x()) << "yaw " << yaw;
      EXPECT_NEAR(fit.dimensions.y(), kMilkTea.y(), 0.05f * kMilkTea.y()) << "yaw " << yaw;
      EXPECT_NEAR(fit.dimensions.z(), kMilkTea.z(), 0.05f * kMilkTea.z()) << "yaw " << yaw;
    }
  }
  std::printf("boxes %d / %zu\n", boxes, 2 * std::size(yaws));
}

// ---- the rules of issue 12: a solid agrees with its points ----

const float kOverreach = ShapeEstimatorParams().max_overreach;

// A table-frame cloud seen from `camera` (table frame), moved into that camera's optical frame
// (camera at the origin, looking at `target`), with the table plane there.
struct CameraView {
  CloudPtr cloud;
  Plane table;
};
CameraView inOpticalFrame(CloudPtr cloud, const Eigen::Vector3f& camera,
                          const Eigen::Vector3f& target) {
  const Eigen::Isometry3f to_camera = synthetic::tableToCamera(camera, target);
  synthetic::transformCloud(to_camera, *cloud);
  return {cloud, synthetic::transformPlane(to_camera, synthetic::tablePlane())};
}

// Lowest and highest coordinate of the cloud along `direction`.
std::pair<float, float> extent(const Cloud& cloud, const Eigen::Vector3f& direction) {
  float low = std::numeric_limits<float>::max(), high = -low;
  for (const auto& p : cloud.points) {
    low = std::min(low, direction.dot(p.getVector3fMap()));
    high = std::max(high, direction.dot(p.getVector3fMap()));
  }
  return {low, high};
}

// Independent of the estimator's own check: the solid's top, a box's footprint along its edges,
// a round solid's diameter across the line of sight stay within `tolerance` of the points.
void expectWithinPoints(const ShapeFit& fit, const Cloud& cloud, const Plane& table,
                        float tolerance, const std::string& what) {
  ASSERT_TRUE(fit.ok) << what << ": " << fit.reason;
  const Eigen::Vector3f up = table.normal;
  const float top = extent(cloud, up).second + table.d;
  const float solid_half_height =
      0.5f * (fit.type == ShapeType::Cube ? fit.dimensions.z() : fit.height);
  EXPECT_LE(up.dot(fit.center) + table.d + solid_half_height, top + tolerance) << what;
  if (fit.type == ShapeType::Cube) {
    for (int axis = 0; axis < 2; ++axis) {
      const Eigen::Vector3f edge = fit.orientation * Eigen::Vector3f::Unit(axis);
      const auto [low, high] = extent(cloud, edge);
      EXPECT_GE(edge.dot(fit.center) - 0.5f * fit.dimensions[axis], low - tolerance) << what;
      EXPECT_LE(edge.dot(fit.center) + 0.5f * fit.dimensions[axis], high + tolerance) << what;
    }
  } else {
    const Eigen::Vector3f sight = fit.center - up.dot(fit.center) * up;
    const Eigen::Vector3f across = up.cross(sight).normalized();
    const auto [low, high] = extent(cloud, across);
    const float radius =
        fit.type == ShapeType::Cone ? std::max(fit.radius_bottom, fit.radius_top) : fit.radius;
    EXPECT_LE(2.0f * radius, high - low + tolerance) << what;
  }
}

void printFit(const char* what, const ShapeFit& fit) {
  std::printf("%s: %s%s %.3f x %.3f x %.3f r %.3f-%.3f h %.3f%s\n", what,
              shapeTypeName(fit.ok ? fit.type : ShapeType::Unknown),
              fit.bounding_box ? " (bounding box)" : "", fit.dimensions.x(), fit.dimensions.y(),
              fit.dimensions.z(), fit.type == ShapeType::Cone ? fit.radius_bottom : fit.radius,
              fit.type == ShapeType::Cone ? fit.radius_top : fit.radius, fit.height,
              fit.truncated ? " truncated" : "");
}

// One face of a flattened bottle (85 mm wide, 175 mm tall): a shallow arc of radius 0.15 m
// facing the camera. A circle through it is 0.3 m across, 3.5 times the object; seen on real
// frames as cones 120-405 mm across. No fitted model is left: its bounding box comes back.
CloudPtr shallowArcFace(const synthetic::Sampler& sampler) {
  const float radius = 0.15f, width = 0.085f, height = 0.175f;
  std::mt19937 rng(sampler.seed);
  std::normal_distribution<float> noise(0.0f, sampler.noise_sigma);
  auto cloud = std::make_shared<Cloud>();
  const float half_angle = std::asin(0.5f * width / radius);
  // Axis behind the face, on the far side from the camera at (0, -0.8, 0.6).
  const Eigen::Vector2f axis(0.0f, radius);
  for (float z = 0.0f; z <= height; z += sampler.spacing) {
    for (float t = -half_angle; t <= half_angle; t += sampler.spacing / radius) {
      const Eigen::Vector3f p(axis.x() + radius * std::sin(t), axis.y() - radius * std::cos(t), z);
      cloud->push_back(Point(p.x() + noise(rng), p.y() + noise(rng), p.z() + noise(rng)));
    }
  }
  cloud->width = static_cast<uint32_t>(cloud->size());
  cloud->height = 1;
  return cloud;
}

TEST(ShapeEstimator, NoSolidIsWiderThanItsPointsAndNoModelLeftGivesTheBoundingBox) {
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  const CameraView view =
      inOpticalFrame(shallowArcFace(sampler), sampler.camera, Eigen::Vector3f(0, 0, 0.09f));
  const ShapeFit fit = ShapeEstimator().estimate(view.cloud, view.table);
  printFit("shallow arc face", fit);
  std::printf("  reason: %s\n", fit.reason.c_str());
  expectWithinPoints(fit, *view.cloud, view.table, kOverreach, "shallow arc face");
  EXPECT_EQ(fit.type, ShapeType::Cube);
  EXPECT_TRUE(fit.bounding_box);
  EXPECT_NE(fit.reason.find("cylinder"), std::string::npos) << fit.reason;
  EXPECT_NE(fit.reason.find("cube"), std::string::npos) << fit.reason;
  // The points' own box: 85 mm chord, the 6 mm sagitta (plus noise), 175 mm tall.
  EXPECT_NEAR(fit.dimensions.x(), 0.085f, 0.005f);
  EXPECT_NEAR(fit.dimensions.y(), 0.006f, 0.005f);
  EXPECT_NEAR(fit.dimensions.z(), 0.175f, 0.005f);
}

TEST(ShapeEstimator, BowlWithoutItsNearRimIsStillACone) {
  // Real OSD bowls (17 cm across) lost their near rim band (a rounded lip seen at grazing
  // incidence): the taper, extrapolated up through the band where the side wall is not fitted
  // (cylinder.top_margin), put the cone's near side 7-8 mm in front of the points, and the bowls
  // were reported as bounding boxes. The near side counts where the wall was measured.
  const float r_bottom = 0.045f, r_top = 0.085f, height = 0.06f;
  const float band = CylinderParams().top_margin;
  for (unsigned seed : {1u, 2u}) {
    synthetic::Sampler sampler = synthetic::voxelGridSampler();
    sampler.seed = seed;
    CloudPtr bowl = synthetic::bowl(r_bottom, r_top, height, 0.004f, {0.0f, 0.0f}, sampler);
    auto cloud = std::make_shared<Cloud>();
    for (const auto& p : bowl->points) {
      if (!(p.z > height - band && p.y < 0.0f)) cloud->push_back(p);  // the camera is at -y
    }
    const CameraView view =
        inOpticalFrame(cloud, sampler.camera, Eigen::Vector3f(0, 0, height / 2));
    const ShapeFit fit = ShapeEstimator().estimate(view.cloud, view.table);
    printFit("bowl without its near rim", fit);
    ASSERT_TRUE(fit.ok) << fit.reason;
    EXPECT_FALSE(fit.bounding_box) << fit.reason;
    ASSERT_EQ(fit.type, ShapeType::Cone) << fit.reason;
    EXPECT_NEAR(fit.radius_top, r_top, 0.005f);
    EXPECT_NEAR(fit.radius_bottom, r_bottom, 0.005f);
  }
}

TEST(ShapeEstimator, BoundingBoxOfABoxIsTheBox) {
  const Eigen::Vector3f size(0.175f, 0.12f, 0.10f);
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  sampler.noise_sigma = 0.0f;
  const CameraView view = inOpticalFrame(synthetic::box(size, {0.0f, 0.0f}, 0.5f, sampler),
                                         sampler.camera, Eigen::Vector3f(0, 0, 0.05f));
  const ShapeFit box = boundingBox(*view.cloud, view.table);
  ASSERT_TRUE(box.ok) << box.reason;
  EXPECT_TRUE(box.bounding_box);
  EXPECT_NEAR(box.dimensions.x(), size.x(), 0.002f);
  EXPECT_NEAR(box.dimensions.y(), size.y(), 0.002f);
  EXPECT_NEAR(box.dimensions.z(), size.z(), 0.001f);
  // Its long edge turned by the box's yaw (0.5 rad) in the table plane.
  const Eigen::Vector3f up = view.table.normal;
  const Eigen::Isometry3f to_camera =
      synthetic::tableToCamera(sampler.camera, Eigen::Vector3f(0, 0, 0.05f));
  const Eigen::Vector3f true_x =
      to_camera.linear() * Eigen::Vector3f(std::cos(0.5f), std::sin(0.5f), 0);
  EXPECT_GT(std::abs((box.orientation * Eigen::Vector3f::UnitX()).dot(true_x)), 0.999f);
  EXPECT_GT((box.orientation * Eigen::Vector3f::UnitZ()).dot(up), 0.9999f);
}

TEST(ShapeEstimator, CapOnABoxCountsInItsHeight) {
  // A flattened bottle: a body 85 x 50 x 155 mm with a round cap (r 14 mm, 20 mm high) on its
  // shoulder. The box fit ends at its top face, the shoulder (the rendered ones came out 156 mm
  // tall for 175); the cap is part of the object. The body alone keeps its height.
  const Eigen::Vector3f body(0.085f, 0.05f, 0.155f);
  const float cap_radius = 0.014f, cap_height = 0.02f;
  for (unsigned seed : {1u, 2u}) {
    synthetic::Sampler sampler = synthetic::voxelGridSampler();
    sampler.seed = seed;
    CloudPtr plain = synthetic::box(body, {0.0f, 0.0f}, 0.3f, sampler);
    auto capped = synthetic::withoutFootprint(plain, -cap_radius, cap_radius, -cap_radius,
                                              cap_radius, body.z());
    *capped += *synthetic::lifted(
        synthetic::roundObject(cap_radius, cap_radius, cap_height, {0.0f, 0.0f}, sampler),
        body.z());
    const Eigen::Vector3f target(0.0f, 0.0f, body.z() / 2);
    const CameraView with_cap = inOpticalFrame(capped, sampler.camera, target);
    const CameraView without = inOpticalFrame(plain, sampler.camera, target);
    const ShapeFit fit = ShapeEstimator().estimate(with_cap.cloud, with_cap.table);
    const ShapeFit body_fit = ShapeEstimator().estimate(without.cloud, without.table);
    printFit("flat bottle with its cap", fit);
    printFit("its body alone", body_fit);
    ASSERT_TRUE(fit.ok && body_fit.ok) << fit.reason << "; " << body_fit.reason;
    ASSERT_EQ(fit.type, ShapeType::Cube);
    EXPECT_FALSE(fit.bounding_box);
    EXPECT_NEAR(fit.dimensions.z(), body.z() + cap_height, 0.004f);
    EXPECT_NEAR(fit.dimensions.x(), body.x(), 0.004f);
    EXPECT_NEAR(fit.dimensions.y(), body.y(), 0.004f);
    // Its bottom stays on the table.
    const float bottom =
        with_cap.table.normal.dot(fit.center) + with_cap.table.d - 0.5f * fit.dimensions.z();
    EXPECT_NEAR(bottom, 0.0f, 0.002f);
    ASSERT_EQ(body_fit.type, ShapeType::Cube);
    EXPECT_NEAR(body_fit.dimensions.z(), body.z(), 0.002f);
  }
}

// A lying cylinder of `radius` and `length`, yawed by `yaw` about up (table frame, camera
// synthetic::Sampler's), within 3 mm on the radius and 1 cm on the length, its axis level and
// along the yaw, its bottom on the table.
void expectLyingCylinder(const ShapeFit& fit, const CameraView& view, float radius, float length,
                         float yaw, float camera_z, const std::string& what) {
  ASSERT_TRUE(fit.ok) << what << ": " << fit.reason;
  ASSERT_EQ(fit.type, ShapeType::Cylinder) << what << ": " << fit.reason;
  EXPECT_NEAR(fit.radius, radius, 0.003f) << what;
  EXPECT_NEAR(fit.height, length, 0.01f) << what;
  const Eigen::Vector3f up = view.table.normal;
  EXPECT_LT(std::abs(fit.axis().dot(up)), 0.05f) << what;  // within 3 degrees of level
  const Eigen::Isometry3f to_camera =
      synthetic::tableToCamera(synthetic::Sampler().camera, Eigen::Vector3f(0, 0, camera_z));
  const Eigen::Vector3f true_axis =
      to_camera.linear() * Eigen::Vector3f(std::cos(yaw), std::sin(yaw), 0);
  EXPECT_GT(std::abs(fit.axis().dot(true_axis)), std::cos(degToRad(5.0f))) << what;
  EXPECT_NEAR(up.dot(fit.center) + view.table.d, radius, 0.003f) << what;  // axis height
}

// expectLyingCylinder() on a lying cylinder sampled as the voxel grid gives it, at each yaw;
// `params` and `view` as the estimator is configured (a RealSense: edge_bleed_px and a view).
void expectLyingCylinderAtYaws(float radius, float length, std::initializer_list<float> yaws,
                               const std::string& what,
                               const ShapeEstimatorParams& params = ShapeEstimatorParams(),
                               const ViewBounds* view_bounds = nullptr) {
  for (float yaw : yaws) {
    synthetic::Sampler sampler = synthetic::voxelGridSampler();
    const CameraView view =
        inOpticalFrame(synthetic::lyingCylinder(radius, length, {0.0f, 0.0f}, yaw, sampler),
                       sampler.camera, Eigen::Vector3f(0, 0, radius));
    const ShapeFit fit = ShapeEstimator(params).estimate(view.cloud, view.table, view_bounds);
    const std::string at = what + " yaw " + std::to_string(yaw);
    printFit(at.c_str(), fit);
    expectLyingCylinder(fit, view, radius, length, yaw, radius, at);
  }
}

TEST(ShapeEstimator, LyingCanIsALyingCylinder) {
  // A soup can (d 66 mm, 101 mm long) lying on its side: real OSD scenes hold such cans and tins
  // standing on their rim (learn30-43), which came out as boxes around them.
  expectLyingCylinderAtYaws(0.033f, 0.101f, {0.0f, 0.5f, 1.0f}, "lying can");
}

TEST(ShapeEstimator, TinOnItsRimIsALyingCylinder) {
  // A cookie tin (d 19 cm, 8 cm deep) standing on its rim, its lid towards the camera (OSD
  // learn34, 37, 38): shorter than wide, the lid's points outnumber the curved band's. Its
  // length is taken at the lid like an upright can's height at its top. The camera looks along
  // +y: at these yaws the axis faces it.
  expectLyingCylinderAtYaws(0.095f, 0.08f, {1.2f, 1.57f, 1.9f}, "tin on its rim");
}

// The view of a camera of focal length `focal_px` whose image spans +-tan_x, +-tan_y (tangents
// of its rays), clusters of voxel centroids `spacing` apart; no near limit known to be reached.
ViewBounds wholeImage(float focal_px, float tan_x, float tan_y, float spacing) {
  ViewBounds view;
  view.known = true;
  view.min_tan_x = -tan_x;
  view.max_tan_x = tan_x;
  view.min_tan_y = -tan_y;
  view.max_tan_y = tan_y;
  view.pixel_tan = 1.0f / focal_px;
  view.point_spacing = spacing;
  return view;
}

TEST(ShapeEstimator, LyingCanIsNotNarrowedWithEdgeSmear) {
  // With a RealSense's edge smear (edge_bleed_px), an upright cylinder wider than its points
  // is narrowed to their median width over height slices (narrowToPoints). A lying can's
  // width across the line of sight may be its length (a tin on its rim seen side on: narrowed,
  // its radius would be half its length), and its height slices are chords of its circle. Its
  // axis along the line of sight or across it, it keeps its radius.
  ShapeEstimatorParams params;
  params.edge_bleed_px = 3.0f;
  // A D435 (fx 385 px) seeing the whole can.
  const ViewBounds view = wholeImage(385.0f, 0.8f, 0.6f, synthetic::voxelGridSampler().spacing);
  expectLyingCylinderAtYaws(0.033f, 0.101f, {0.0f, 1.57f}, "lying can, edge smear", params, &view);
  // A tin on its rim seen side on: 8 cm across the line of sight, half its 19 cm diameter.
  expectLyingCylinderAtYaws(0.095f, 0.08f, {0.0f}, "tin on its rim, edge smear", params, &view);
}

// `cloud` (optical frame) with an active-stereo camera's smear above its top in the image: in
// every column `spacing` wide, its topmost point repeated 1, 2 and 3 pixels (`pixel_tan`) higher
// in the image, at its own depth.
CloudPtr withSmearAboveTop(const Cloud& cloud, float pixel_tan, float spacing) {
  std::map<int, Point> topmost;
  for (const auto& p : cloud.points) {
    auto [it, inserted] = topmost.emplace(static_cast<int>(std::floor(p.x / spacing)), p);
    if (!inserted && p.y / p.z < it->second.y / it->second.z) it->second = p;
  }
  auto smeared = std::make_shared<Cloud>(cloud);
  for (const auto& [column, top] : topmost) {
    for (int px = 1; px <= 3; ++px) {
      Point q = top;
      q.y = (top.y / top.z - static_cast<float>(px) * pixel_tan) * top.z;
      smeared->push_back(q);
    }
  }
  return smeared;
}

TEST(ShapeEstimator, LyingCanIsMeasuredWithoutTheSmearAboveIt) {
  // A D435 smears a lying can's upper outline up to 3 px over the background behind it, at the
  // can's depth: on the rendered everyday scenes those points made its radius 3-13 % large. The
  // chosen lying cylinder's circle is refitted without them: r 33 mm within 0.5 mm. Not told of
  // the smear (edge_bleed_px 0), the estimator keeps them and measures it over 1 mm larger.
  // (At yaw 0 its ends are its sides across the line of sight, whose smear, not drawn here,
  // another rule trims: its length is that rule's.)
  const float radius = 0.033f, length = 0.101f;
  const ViewBounds view = wholeImage(385.0f, 0.8f, 0.6f, synthetic::voxelGridSampler().spacing);
  ShapeEstimatorParams smear_known;
  smear_known.edge_bleed_px = 3.0f;
  // (From yaw 1 on, the box around these points explains them better: a lying can's box is a
  // right solid too, and is not what this rule measures.)
  for (float yaw : {0.0f, 0.5f}) {
    synthetic::Sampler sampler = synthetic::voxelGridSampler();
    CameraView can =
        inOpticalFrame(synthetic::lyingCylinder(radius, length, {0.0f, 0.0f}, yaw, sampler),
                       sampler.camera, Eigen::Vector3f(0, 0, radius));
    can.cloud = withSmearAboveTop(*can.cloud, view.pixel_tan, sampler.spacing);
    const std::string what = "lying can, smear above, yaw " + std::to_string(yaw);
    const ShapeFit fit = ShapeEstimator(smear_known).estimate(can.cloud, can.table, &view);
    printFit(what.c_str(), fit);
    ASSERT_TRUE(fit.ok && fit.type == ShapeType::Cylinder) << what << ": " << fit.reason;
    EXPECT_LT(std::abs(fit.axis().dot(can.table.normal)), 0.05f) << what;  // lying
    EXPECT_NEAR(can.table.normal.dot(fit.center) + can.table.d, radius, 0.001f) << what;
    EXPECT_NEAR(fit.radius, radius, 0.0005f) << what;
    const ShapeFit kept = ShapeEstimator().estimate(can.cloud, can.table, &view);
    printFit((what + ", smear unknown").c_str(), kept);
    ASSERT_TRUE(kept.ok && kept.type == ShapeType::Cylinder) << what << ": " << kept.reason;
    EXPECT_GT(kept.radius, radius + 0.001f) << what;
    if (yaw > 0.0f) {
      // Its axis partly along the line of sight, its far end faces up the image: the smear
      // there made it 2 mm long; that end moves in by the smear's part along the axis.
      EXPECT_NEAR(fit.height, length, 0.0015f) << what;
      EXPECT_GT(kept.height, length + 0.0015f) << what;
    }
  }
}

TEST(ShapeEstimator, OpenMugIsAsTallAsItsRimWithoutTheSmearAboveIt) {
  // A D435 smears the far rim of a mug (d 82, h 95 mm, open) up to 3 px over the background
  // behind it, at the rim's depth: on a steep view those points stand over the rim, a group of
  // their own that the top's height follows (RealSense renders: mugs 97-100 mm for 95). The
  // chosen upright cylinder's top is that of the cylinder refitted without them: 95 mm within
  // 0.8 mm (96.3 before). Not told of the smear (edge_bleed_px 0), the estimator keeps them: the
  // mug comes out taller.
  const float radius = 0.041f, height = 0.095f, wall = 0.004f;
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  sampler.camera = {0.0f, -0.7f, 0.8f};  // 1.06 m away, 49 degrees down
  const ViewBounds view = wholeImage(385.0f, 0.8f, 0.6f, sampler.spacing);
  CameraView mug =
      inOpticalFrame(synthetic::bowl(radius, radius, height, wall, {0.0f, 0.0f}, sampler),
                     sampler.camera, Eigen::Vector3f(0, 0, height / 2));
  mug.cloud = withSmearAboveTop(*mug.cloud, view.pixel_tan, sampler.spacing);
  ShapeEstimatorParams smear_known;
  smear_known.edge_bleed_px = 3.0f;
  const ShapeFit fit = ShapeEstimator(smear_known).estimate(mug.cloud, mug.table, &view);
  printFit("mug, smear above", fit);
  ASSERT_TRUE(fit.ok && fit.type == ShapeType::Cylinder) << fit.reason;
  EXPECT_NEAR(fit.height, height, 0.0008f);
  EXPECT_NEAR(mug.table.normal.dot(fit.center) + mug.table.d, height / 2, 0.001f);
  const ShapeFit kept = ShapeEstimator().estimate(mug.cloud, mug.table, &view);
  printFit("mug, smear above, smear unknown", kept);
  ASSERT_TRUE(kept.ok) << kept.reason;
  EXPECT_GT(kept.type == ShapeType::Cube ? kept.dimensions.z() : kept.height, height + 0.0015f);
}

TEST(ShapeEstimator, HalfHiddenLyingCanIsALyingCylinder) {
  // A Pringles can (r 37 mm, 23 cm long) lying behind a box, which hides its lower half: only
  // the upper part of its curved wall is seen (learn30, learn32). Its circle still follows from
  // that arc, and its bottom rests on the table.
  const float radius = 0.037f, length = 0.23f;
  for (float yaw : {0.0f, 0.3f}) {
    synthetic::Sampler sampler = synthetic::voxelGridSampler();
    CloudPtr can = synthetic::lyingCylinder(radius, length, {0.0f, 0.0f}, yaw, sampler);
    auto upper = std::make_shared<Cloud>();
    for (const auto& p : can->points) {
      if (p.z > radius) upper->push_back(p);  // the box in front hides the rest
    }
    const CameraView view = inOpticalFrame(upper, sampler.camera, Eigen::Vector3f(0, 0, radius));
    const ShapeFit fit = ShapeEstimator().estimate(view.cloud, view.table);
    const std::string what = "half hidden lying can yaw " + std::to_string(yaw);
    printFit(what.c_str(), fit);
    expectLyingCylinder(fit, view, radius, length, yaw, radius, what);
  }
}

// `cloud` without the points lower than `depth` under the top at `height`: what neighbours of
// the same height, touching it, leave in view of an object in a crowd.
CloudPtr onlyTheTop(const CloudPtr& cloud, float height, float depth) {
  auto top = std::make_shared<Cloud>();
  for (const auto& p : cloud->points) {
    if (p.z > height - depth) top->push_back(p);
  }
  return top;
}

// `object` (table frame, standing on the table, `height` tall) as a crowd leaves it in view: its
// top and the top `seen` of its wall (onlyTheTop), in the optical frame of the sampler's camera.
CameraView seenAtItsTop(const CloudPtr& object, float height, float seen,
                        const synthetic::Sampler& sampler) {
  return inOpticalFrame(onlyTheTop(object, height, seen), sampler.camera,
                        Eigen::Vector3f(0.0f, 0.0f, height / 2));
}

TEST(ShapeEstimator, CanInACrowdSeenOnlyAtItsTopIsACylinder) {
  // A can (r 44 mm, 110 mm) among neighbours that hide all but the top 15 mm of its wall
  // (rendered touching clutter): too few wall points for the round fit, and the box around its
  // lid won. Its lid's round outline makes it the cylinder. A box of the same size so seen
  // stays a box.
  const float radius = 0.044f, height = 0.11f, seen = 0.015f;
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  const Eigen::Vector3f target(0.0f, 0.0f, height / 2);
  const CameraView can = seenAtItsTop(
      synthetic::roundObject(radius, radius, height, {0.0f, 0.0f}, sampler), height, seen, sampler);
  const ShapeFit fit = ShapeEstimator().estimate(can.cloud, can.table);
  printFit("can seen at its top", fit);
  ASSERT_TRUE(fit.ok) << fit.reason;
  ASSERT_EQ(fit.type, ShapeType::Cylinder) << fit.reason;
  EXPECT_NEAR(fit.radius, radius, 0.003f);
  EXPECT_NEAR(fit.height, height, 0.005f);
  const Eigen::Vector3f axis_foot =
      fit.center - (can.table.normal.dot(fit.center) + can.table.d) * can.table.normal;
  const Eigen::Vector3f true_foot =
      synthetic::tableToCamera(sampler.camera, target) * Eigen::Vector3f::Zero();
  EXPECT_LT((axis_foot - true_foot).norm(), 0.003f);
  for (float yaw : {0.0f, 0.5f}) {
    const Eigen::Vector3f size(2.0f * radius, 2.0f * radius, height);
    const CameraView box =
        seenAtItsTop(synthetic::box(size, {0.0f, 0.0f}, yaw, sampler), height, seen, sampler);
    const ShapeFit box_fit = ShapeEstimator().estimate(box.cloud, box.table);
    printFit("box seen at its top", box_fit);
    EXPECT_EQ(box_fit.type, ShapeType::Cube) << "yaw " << yaw;
  }
}

// `cloud` (table frame) without the points the camera at `camera` sees through the upright box
// `occluder` (axis-aligned, from `low` to `high` corner): what a neighbour in front hides.
CloudPtr hiddenBehind(const CloudPtr& cloud, const Eigen::Vector3f& camera,
                      const Eigen::AlignedBox3f& occluder) {
  auto seen = std::make_shared<Cloud>();
  for (const auto& p : cloud->points) {
    const Eigen::Vector3f point = p.getVector3fMap(), ray = camera - point;
    // The slab test along the segment from the point to the camera.
    float enter = 0.0f, leave = 1.0f;
    for (int axis = 0; axis < 3 && enter <= leave; ++axis) {
      const float low = (occluder.min()[axis] - point[axis]) / ray[axis];
      const float high = (occluder.max()[axis] - point[axis]) / ray[axis];
      enter = std::max(enter, std::min(low, high));
      leave = std::min(leave, std::max(low, high));
    }
    if (enter > leave) seen->push_back(p);
  }
  return seen;
}

TEST(ShapeEstimator, CanWhoseLidATallerNeighbourPartlyHidesIsACylinder) {
  // A can (r 41 mm, 110 mm) in a crowd: its neighbours hide all but the top 15 mm of its wall, and
  // a taller box (140 or 150 mm) standing 2 mm in front of it hides the near part of its lid
  // (rendered touching clutter). The outline's best circle ran through the cut and part of the
  // rim (r 22-34 mm for 44), or covered too short an arc, and the box around the visible part of
  // the lid won. The circle that holds the whole outline, with the far rim on it and the box's far
  // corners empty, makes it the cylinder. A box of the same size so hidden stays a box. The
  // circle rests on the far half of the rim only, 1 mm noise on it: r 38-40 mm, its axis 3 mm
  // towards the far side (the sampler's outermost lid ring lies 1 mm inside the rim).
  const float radius = 0.041f, height = 0.11f, seen = 0.015f;
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  sampler.camera = Eigen::Vector3f(0.0f, -0.75f, 0.75f);  // 1.06 m away, 45 degrees down
  const Eigen::Vector3f target(0.0f, 0.0f, height / 2);
  for (float neighbour_height : {0.14f, 0.15f}) {
    const Eigen::AlignedBox3f neighbour(
        Eigen::Vector3f(-radius, -radius - 0.082f, 0.0f),
        Eigen::Vector3f(radius, -radius - 0.002f, neighbour_height));
    const CameraView can = inOpticalFrame(
        hiddenBehind(
            onlyTheTop(synthetic::roundObject(radius, radius, height, {0.0f, 0.0f}, sampler),
                       height, seen),
            sampler.camera, neighbour),
        sampler.camera, target);
    const std::string what =
        "can, lid partly hidden by a neighbour " + std::to_string(neighbour_height) + " m tall";
    const ShapeFit fit = ShapeEstimator().estimate(can.cloud, can.table);
    printFit(what.c_str(), fit);
    ASSERT_TRUE(fit.ok) << what << ": " << fit.reason;
    ASSERT_EQ(fit.type, ShapeType::Cylinder) << what;
    EXPECT_NEAR(fit.radius, radius, 0.003f) << what;
    EXPECT_NEAR(fit.height, height, 0.005f) << what;
    const Eigen::Vector3f axis_foot =
        fit.center - (can.table.normal.dot(fit.center) + can.table.d) * can.table.normal;
    const Eigen::Vector3f true_foot =
        synthetic::tableToCamera(sampler.camera, target) * Eigen::Vector3f::Zero();
    EXPECT_LT((axis_foot - true_foot).norm(), 0.004f) << what;
    for (float yaw : {0.0f, 0.5f}) {
      const Eigen::Vector3f size(2.0f * radius, 2.0f * radius, height);
      const CameraView box = inOpticalFrame(
          hiddenBehind(onlyTheTop(synthetic::box(size, {0.0f, 0.0f}, yaw, sampler), height, seen),
                       sampler.camera, neighbour),
          sampler.camera, target);
      const ShapeFit box_fit = ShapeEstimator().estimate(box.cloud, box.table);
      printFit(("box so hidden, yaw " + std::to_string(yaw)).c_str(), box_fit);
      EXPECT_EQ(box_fit.type, ShapeType::Cube) << what << ", box yaw " << yaw;
    }
  }
}

TEST(ShapeEstimator, CanWhoseModelsAllFailIsStillTheCylinderUnderItsLid) {
  // When no model passes, the cluster's bounding box was all we gave, even around a round lid: a
  // rendered can whose box fit found degenerate extents and whose round fit rested on 40 of its
  // 489 points, and a real OSD one (learn34) whose box and cone both broke a rule. The lid rules
  // apply to the bounding box too. Here the box fit is made to fail (no plane may hold less than
  // all the points) on a can seen only at its top 15 mm, whose round fit has too few wall points.
  const float radius = 0.044f, height = 0.11f, seen = 0.015f;
  const synthetic::Sampler sampler = synthetic::voxelGridSampler();
  const CameraView can = seenAtItsTop(
      synthetic::roundObject(radius, radius, height, {0.0f, 0.0f}, sampler), height, seen, sampler);
  ShapeEstimatorParams no_box;
  no_box.cube.min_support_fraction = 1.0f;
  const ShapeFit fit = ShapeEstimator(no_box).estimate(can.cloud, can.table);
  printFit("can seen at its top, no box fit", fit);
  ASSERT_TRUE(fit.ok) << fit.reason;
  ASSERT_EQ(fit.type, ShapeType::Cylinder) << fit.reason;
  EXPECT_FALSE(fit.bounding_box);
  EXPECT_NEAR(fit.radius, radius, 0.003f);
  EXPECT_NEAR(fit.height, height, 0.005f);
  // A box of the same size so seen stays its bounding box.
  const Eigen::Vector3f size(2.0f * radius, 2.0f * radius, height);
  const CameraView box =
      seenAtItsTop(synthetic::box(size, {0.0f, 0.0f}, 0.5f, sampler), height, seen, sampler);
  const ShapeFit box_fit = ShapeEstimator(no_box).estimate(box.cloud, box.table);
  printFit("box seen at its top, no box fit", box_fit);
  EXPECT_EQ(box_fit.type, ShapeType::Cube);
  EXPECT_TRUE(box_fit.bounding_box);
}

TEST(ShapeEstimator, BoxCutByTheImageBorderIsNeverRound) {
  // The tall narrow box (89 x 38 x 175 mm) cut by the image's right border came out as a
  // cylinder 452 mm across on a real frame; the paper's teapot box too, at several yaws and
  // cuts. Camera 1 m away, 37 degrees down, in its optical frame: the border is a bound on x / z.
  const Eigen::Vector3f boxes[] = {{0.089f, 0.038f, 0.175f}, {0.175f, 0.12f, 0.10f}};
  int truncated = 0, cases = 0;
  for (const Eigen::Vector3f& size : boxes) {
    for (float yaw : {0.0f, 0.6f, 1.2f}) {
      for (float kept : {0.35f, 0.6f}) {
        synthetic::Sampler sampler = synthetic::voxelGridSampler();
        CameraView view = inOpticalFrame(synthetic::box(size, {0.0f, 0.0f}, yaw, sampler),
                                         sampler.camera, Eigen::Vector3f(0, 0, size.z() / 2));
        float low = std::numeric_limits<float>::max(), high = -low;
        for (const auto& p : view.cloud->points) {
          low = std::min(low, p.x / p.z);
          high = std::max(high, p.x / p.z);
        }
        ViewBounds bounds;
        bounds.known = true;
        bounds.pixel_tan = 1.0f / 575.8f;
        bounds.point_spacing = sampler.spacing;
        bounds.min_tan_x = -0.55f;
        bounds.max_tan_x = low + kept * (high - low);
        bounds.min_tan_y = -0.42f;
        bounds.max_tan_y = 0.42f;
        Cloud cut;
        for (const auto& p : view.cloud->points) {
          if (p.x / p.z <= bounds.max_tan_x) cut.push_back(p);
        }
        const CloudPtr cluster = std::make_shared<Cloud>(cut);
        const ShapeFit fit = ShapeEstimator().estimate(cluster, view.table, &bounds);
        char what[96];
        std::snprintf(what, sizeof what, "box %.3f x %.3f x %.3f yaw %.1f, %.0f %% of it in view",
                      size.x(), size.y(), size.z(), yaw, 100 * kept);
        printFit(what, fit);
        ++cases;
        ASSERT_TRUE(fit.ok) << what << ": " << fit.reason;
        EXPECT_EQ(fit.type, ShapeType::Cube) << what;
        EXPECT_TRUE(fit.truncated) << what;
        truncated += fit.truncated;
        expectWithinPoints(fit, *cluster, view.table, kOverreach, what);
        // The cut runs through the box's footprint: a horizontal edge is a lower bound, the
        // height is not (the camera's x axis is level).
        EXPECT_TRUE(fit.lower_bound[0] || fit.lower_bound[1]) << what;
        EXPECT_FALSE(fit.lower_bound[2]) << what;
      }
    }
  }
  std::printf("truncated %d / %d\n", truncated, cases);
}

// `cloud` (optical frame) with an active-stereo camera's smear beside its sides in the image: in
// every row `spacing` high, its leftmost and rightmost points repeated 1, 2 and 3 pixels
// (`pixel_tan`) farther out, at their own depth.
CloudPtr withSmearBesideSides(const Cloud& cloud, float pixel_tan, float spacing) {
  std::map<int, std::pair<Point, Point>> sides;  // leftmost, rightmost per row
  for (const auto& p : cloud.points) {
    auto [it, inserted] =
        sides.emplace(static_cast<int>(std::floor(p.y / spacing)), std::pair{p, p});
    if (p.x / p.z < it->second.first.x / it->second.first.z) it->second.first = p;
    if (p.x / p.z > it->second.second.x / it->second.second.z) it->second.second = p;
  }
  auto smeared = std::make_shared<Cloud>(cloud);
  for (const auto& [row, side] : sides) {
    for (int px = 1; px <= 3; ++px) {
      for (const auto& [edge, outward] :
           {std::pair{side.first, -1.0f}, std::pair{side.second, 1.0f}}) {
        Point q = edge;
        q.x = (edge.x / edge.z + outward * static_cast<float>(px) * pixel_tan) * edge.z;
        smeared->push_back(q);
      }
    }
  }
  return smeared;
}

TEST(ShapeEstimator, MarkerWhoseTopLeavesTheImageKeepsItsWidth) {
  // An 18 mm marker, 140 mm tall, beside the image's side on a steep view: its vertical edges
  // lean outward in the image and only its top reaches the border (RealSense seed 99: a marker at
  // 0.46 m came out r 11.3 mm, its width rules off as if the border had cut it across). The
  // border cuts its height, not its width: its radius is the thin object's (9 mm within 1.5),
  // its height a lower bound, its radius not.
  const float radius = 0.009f, height = 0.14f;
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  sampler.camera = {0.0f, -0.45f, 0.55f};
  const ViewBounds whole = wholeImage(385.0f, 0.8f, 0.6f, sampler.spacing);  // a D435's
  const CameraView view =
      inOpticalFrame(synthetic::roundObject(radius, radius, height, {0.22f, 0.05f}, sampler),
                     sampler.camera, Eigen::Vector3f(0, 0, 0.07f));
  const CloudPtr smeared = withSmearBesideSides(*view.cloud, whole.pixel_tan, sampler.spacing);
  // The border where the outer side of the marker's lower 60 % ends, 3 px out: its top leans
  // beyond it.
  const float outward = view.cloud->points[0].x > 0.0f ? 1.0f : -1.0f;
  float lower_side = 0.0f;
  for (const auto& p : smeared->points) {
    if (view.table.normal.dot(p.getVector3fMap()) + view.table.d < 0.6f * height)
      lower_side = std::max(lower_side, outward * p.x / p.z);
  }
  ViewBounds bounds = whole;
  (outward > 0.0f ? bounds.max_tan_x : bounds.min_tan_x) =
      outward * (lower_side + 3.0f * whole.pixel_tan);
  auto cut = std::make_shared<Cloud>();
  for (const auto& p : smeared->points) {
    if (outward * p.x / p.z <= outward * (outward > 0.0f ? bounds.max_tan_x : bounds.min_tan_x))
      cut->push_back(p);
  }
  ASSERT_LT(cut->size(), smeared->size()) << "the border cuts its top";
  ShapeEstimatorParams params;
  params.edge_bleed_px = 3.0f;
  const ShapeFit fit = ShapeEstimator(params).estimate(cut, view.table, &bounds);
  printFit("marker whose top leaves the image", fit);
  ASSERT_TRUE(fit.ok) << fit.reason;
  EXPECT_EQ(fit.type, ShapeType::Cylinder);
  EXPECT_NEAR(fit.radius, radius, 0.0015f);
  EXPECT_TRUE(fit.truncated);
  EXPECT_TRUE(fit.lower_bound[2]) << "its height";
  EXPECT_FALSE(fit.lower_bound[0] || fit.lower_bound[1]) << "its radius";
  // Seen whole, it is measured alike.
  const ShapeFit whole_fit = ShapeEstimator(params).estimate(smeared, view.table, &whole);
  printFit("marker in view", whole_fit);
  EXPECT_NEAR(whole_fit.radius, radius, 0.0015f);
  EXPECT_FALSE(whole_fit.truncated);
}

TEST(ShapeEstimator, BowlWhoseRimLeavesTheImageIsCutAcross) {
  // A bowl (foot r 40, rim r 75 mm, 65 mm high) beside the image's side: only its rim, in the
  // upper half of its height, reaches the border, but the rim is its widest part, so the border
  // cuts it across, unlike a marker's top (MarkerWhoseTopLeavesTheImageKeepsItsWidth). Its radius
  // is a lower bound, its height is not.
  const float r_bottom = 0.04f, r_top = 0.075f, height = 0.065f;
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  sampler.camera = {0.0f, -0.45f, 0.55f};
  const ViewBounds whole = wholeImage(385.0f, 0.8f, 0.6f, sampler.spacing);
  const CameraView view =
      inOpticalFrame(synthetic::bowl(r_bottom, r_top, height, 0.004f, {0.2f, 0.05f}, sampler),
                     sampler.camera, Eigen::Vector3f(0, 0, 0.03f));
  // The border 1 cm inside the rim's outer side, beyond the foot's.
  const float outward = view.cloud->points[0].x > 0.0f ? 1.0f : -1.0f;
  float rim_side = 0.0f, foot_side = 0.0f;
  for (const auto& p : view.cloud->points) {
    const float h = view.table.normal.dot(p.getVector3fMap()) + view.table.d;
    float& side = h > 0.5f * height ? rim_side : foot_side;
    side = std::max(side, outward * p.x / p.z);
  }
  ASSERT_GT(rim_side - 0.01f / 0.7f, foot_side);
  ViewBounds bounds = whole;
  (outward > 0.0f ? bounds.max_tan_x : bounds.min_tan_x) = outward * (rim_side - 0.01f / 0.7f);
  auto cut = std::make_shared<Cloud>();
  for (const auto& p : view.cloud->points) {
    if (outward * p.x / p.z <= rim_side - 0.01f / 0.7f) cut->push_back(p);
  }
  const ShapeFit fit = ShapeEstimator().estimate(cut, view.table, &bounds);
  printFit("bowl whose rim leaves the image", fit);
  ASSERT_TRUE(fit.ok) << fit.reason;
  EXPECT_TRUE(fit.truncated);
  EXPECT_TRUE(fit.lower_bound[0] && fit.lower_bound[1]) << "its radius";
  EXPECT_FALSE(fit.lower_bound[2]) << "its height";
}

TEST(ShapeEstimator, WholeObjectsInViewAreNotTruncated) {
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  const CameraView view = inOpticalFrame(synthetic::box(kMilkTea, {0.0f, 0.0f}, 0.3f, sampler),
                                         sampler.camera, Eigen::Vector3f(0, 0, kMilkTea.z() / 2));
  const ViewBounds bounds = wholeImage(575.8f, 0.55f, 0.42f, sampler.spacing);
  const ShapeFit fit = ShapeEstimator().estimate(view.cloud, view.table, &bounds);
  ASSERT_TRUE(fit.ok) << fit.reason;
  EXPECT_FALSE(fit.truncated);
  EXPECT_FALSE(fit.lower_bound[0] || fit.lower_bound[1] || fit.lower_bound[2]);
}

TEST(ShapeEstimator, NearestObjectIsCutOnlyAtTheCamerasNearLimit) {
  // A soup can (d 66, h 101 mm) 0.55 m from the camera, the nearest object of its frame: the
  // frame's nearest depth is its own. A RealSense (near limit 0.28 m) saw all of it; a camera
  // whose near limit is that depth cut it there, towards the camera; a camera of unknown near
  // limit is taken as cut by it within 0.6 m.
  synthetic::Sampler sampler = synthetic::voxelGridSampler();
  sampler.camera = {0.0f, -0.5f, 0.4f};
  const CameraView view =
      inOpticalFrame(synthetic::roundObject(0.033f, 0.033f, 0.101f, {0.0f, 0.0f}, sampler),
                     sampler.camera, Eigen::Vector3f(0, 0, 0.05f));
  float nearest = std::numeric_limits<float>::max();
  for (const auto& p : view.cloud->points) nearest = std::min(nearest, p.z);
  ASSERT_GT(nearest, 0.5f);
  ASSERT_LT(nearest, 0.6f);
  ViewBounds bounds = wholeImage(385.0f, 0.8f, 0.6f, sampler.spacing);  // a D435's
  bounds.min_depth = nearest;
  struct Case {
    float near_limit;
    bool cut;
  };
  for (const Case& c : {Case{0.28f, false}, Case{nearest - 0.01f, true}, Case{0.0f, true}}) {
    ShapeEstimatorParams params;
    params.near_limit = c.near_limit;
    const ShapeFit fit = ShapeEstimator(params).estimate(view.cloud, view.table, &bounds);
    const std::string what = "near limit " + std::to_string(c.near_limit);
    printFit(what.c_str(), fit);
    ASSERT_TRUE(fit.ok) << what << ": " << fit.reason;
    EXPECT_EQ(fit.truncated, c.cut) << what;
    if (c.cut) continue;
    EXPECT_EQ(fit.type, ShapeType::Cylinder) << what;
    EXPECT_NEAR(fit.radius, 0.033f, 0.003f) << what;
    EXPECT_NEAR(fit.height, 0.101f, 0.005f) << what;
  }
}

TEST(ViewBounds, FromAnOrganisedCloud) {
  // 640 x 480 pixels, f = 575.8 px, a wall 1 m away; the first 10 columns have no return.
  const float f = 575.8f, cx = 319.5f, cy = 239.5f;
  pcl::PointCloud<pcl::PointXYZ> cloud(640, 480);
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      const float nan = std::numeric_limits<float>::quiet_NaN();
      cloud.at(u, v) =
          u < 10 ? pcl::PointXYZ(nan, nan, nan) : pcl::PointXYZ((u - cx) / f, (v - cy) / f, 1.0f);
    }
  }
  const ViewBounds view = viewBoundsOf(cloud);
  ASSERT_TRUE(view.known);
  EXPECT_NEAR(view.min_tan_x, (10 - cx) / f, 1e-5f);
  EXPECT_NEAR(view.max_tan_x, (639 - cx) / f, 1e-5f);
  EXPECT_NEAR(view.min_tan_y, (0 - cy) / f, 1e-5f);
  EXPECT_NEAR(view.max_tan_y, (479 - cy) / f, 1e-5f);
  EXPECT_NEAR(view.pixel_tan, 1.0f / f, 1e-6f);
  pcl::PointCloud<pcl::PointXYZ> unorganised;
  unorganised.push_back(pcl::PointXYZ(0, 0, 1));
  EXPECT_FALSE(viewBoundsOf(unorganised).known);
}

}  // namespace
}  // namespace tabletop_shapes
