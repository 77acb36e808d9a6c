// §3.3 cylinder fit and the truncated cone: known-answer tests on synthetic clouds, in the table
// frame and in a tilted camera-like frame (camera 1 m away, ~37 degrees above the table).
#include "tabletop_shapes/core/cylinder_fit.h"
#include "tabletop_shapes/core/normals.h"

#include "synthetic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

namespace tabletop_shapes {
namespace {

using synthetic::Sampler;

// The paper's objects (SPEC.md ground truth).
const float kMugRadius = 0.0415f, kMugHeight = 0.16f;
const float kBeakerBottom = 0.03f, kBeakerTop = 0.0375f, kBeakerHeight = 0.18f;
const Eigen::Vector2f kObjectCentre(0.05f, 0.02f);  // on the table, off the frame's origin

// Points on a circle arc of `degrees` centred at angle 0, with isotropic 2-D noise, or with
// noise along x only: the depth noise of a distant camera on the +x side looking at the arc.
std::vector<Eigen::Vector2f> arc(const Eigen::Vector2f& centre, float radius, float degrees,
                                 int count, float sigma, unsigned seed, bool along_ray = false) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, sigma > 0 ? sigma : 1.0f);
  std::vector<Eigen::Vector2f> points;
  const float span = degToRad(degrees);
  for (int i = 0; i < count; ++i) {
    const float t = -span / 2 + span * i / (count - 1);
    Eigen::Vector2f p = centre + radius * Eigen::Vector2f(std::cos(t), std::sin(t));
    if (sigma > 0) {
      p.x() += noise(rng);
      if (!along_ray) p.y() += noise(rng);
    }
    points.push_back(p);
  }
  return points;
}

// Kinect-like noise: mostly along the viewing ray (depth), on top of the sampler's isotropic
// noise. Table frame.
void addRayNoise(const Eigen::Vector3f& camera, float sigma, unsigned seed, Cloud& cloud) {
  std::mt19937 rng(seed + 1000);
  std::normal_distribution<float> noise(0.0f, sigma);
  for (auto& p : cloud.points) {
    const Eigen::Vector3f ray = (p.getVector3fMap() - camera).normalized();
    p.getVector3fMap() += noise(rng) * ray;
  }
}

// Analytic normals of a table-frame round-object cloud: the normal of the nearest surface
// (top disc or side wall of the cone r(z) = r_bottom + slope z).
NormalCloud analyticNormals(const Cloud& cloud, float r_bottom, float r_top, float height,
                            const Eigen::Vector2f& centre) {
  const float slope = (r_top - r_bottom) / height;
  NormalCloud out;
  for (const auto& p : cloud.points) {
    const Eigen::Vector2f radial = p.getVector3fMap().head<2>() - centre;
    const float side_distance = std::abs(radial.norm() - (r_bottom + slope * p.z));
    const float top_distance = std::abs(p.z - height);
    Eigen::Vector3f n = Eigen::Vector3f::UnitZ();
    if (side_distance < top_distance || radial.norm() > r_top) {
      const Eigen::Vector2f dir = radial.normalized();
      n = Eigen::Vector3f(dir.x(), dir.y(), -slope).normalized();
    }
    pcl::PointNormal q;
    q.getVector3fMap() = p.getVector3fMap();
    q.getNormalVector3fMap() = n;
    out.push_back(q);
  }
  return out;
}

using synthetic::tableToCamera;

void transformNormalCloud(const Eigen::Isometry3f& T, NormalCloud& cloud) {
  for (auto& p : cloud.points) {
    p.getVector3fMap() = T * p.getVector3fMap();
    p.getNormalVector3fMap() = T.linear() * p.getNormalVector3fMap();
  }
}

// A round object as the fit sees it: sampled in the table frame with Kinect-like noise, then
// moved into the camera frame. Normals analytic, or by MLS (normals.h) on the camera cloud.
struct Scene {
  NormalCloud object;
  Plane table;
  Eigen::Isometry3f table_to_camera;
};

// A mug's handle: the outer bar of a loop 25 mm outside the wall, on the side facing the camera.
void addHandle(float radius, float height, Cloud& cloud) {
  const float angle = degToRad(-60.0f);
  const Eigen::Vector2f out(std::cos(angle), std::sin(angle)), along(-out.y(), out.x());
  for (float z = 0.25f * height; z <= 0.75f * height; z += 0.004f) {
    for (float t = -0.006f; t <= 0.0061f; t += 0.004f) {
      const Eigen::Vector2f p = kObjectCentre + (radius + 0.025f) * out + t * along;
      cloud.push_back(Point(p.x(), p.y(), z));
    }
  }
}

// Camera (0, -0.8, camera_height); at 0.6 m: 1 m away, 37 degrees above the table.
Sampler roundSampler(unsigned seed, float camera_height = 0.6f) {
  Sampler sampler;
  sampler.camera.z() = camera_height;
  sampler.spacing = 0.004f;
  sampler.noise_sigma = 0.0005f;
  sampler.seed = seed;
  return sampler;
}

// The camera pose and the table of an object `height` tall seen by `sampler`.
Scene sceneFor(const Sampler& sampler, float height) {
  Scene scene;
  scene.table_to_camera = tableToCamera(
      sampler.camera, Eigen::Vector3f(kObjectCentre.x(), kObjectCentre.y(), height / 2));
  scene.table = synthetic::transformPlane(scene.table_to_camera, synthetic::tablePlane());
  return scene;
}

// `cloud` (table frame) moved into the camera frame of `scene`, with MLS normals.
void withMlsNormals(const CloudPtr& cloud, Scene& scene) {
  synthetic::transformCloud(scene.table_to_camera, *cloud);
  estimateNormalsMLS(cloud, NormalParams{}, scene.object);
}

Scene roundScene(float r_bottom, float r_top, float height, unsigned seed, bool mls_normals,
                 float ray_sigma = 0.002f, bool handle = false, float camera_height = 0.6f) {
  const Sampler sampler = roundSampler(seed, camera_height);
  CloudPtr cloud = synthetic::roundObject(r_bottom, r_top, height, kObjectCentre, sampler);
  addRayNoise(sampler.camera, ray_sigma, seed, *cloud);
  if (handle) addHandle(r_bottom, height, *cloud);
  Scene scene = sceneFor(sampler, height);
  if (mls_normals) {
    withMlsNormals(cloud, scene);
  } else {
    scene.object = analyticNormals(*cloud, r_bottom, r_top, height, kObjectCentre);
    transformNormalCloud(scene.table_to_camera, scene.object);
  }
  return scene;
}

// Centre of the solid in the camera frame.
Eigen::Vector3f trueCentre(const Scene& scene, float height) {
  return scene.table_to_camera * Eigen::Vector3f(kObjectCentre.x(), kObjectCentre.y(), height / 2);
}

// ---- circles ----

TEST(CircleFit, AlgebraicIsExactWithoutNoiseFarFromTheOrigin) {
  const Eigen::Vector2f centre(3.0f, -2.0f);
  for (float degrees : {30.0f, 90.0f, 360.0f}) {
    const Circle circle = fitCircleAlgebraic(arc(centre, 0.04f, degrees, 50, 0.0f, 1));
    ASSERT_TRUE(circle.ok) << degrees;
    EXPECT_NEAR(circle.radius, 0.04f, 2e-5f) << degrees;
    EXPECT_LT((circle.center - centre).norm(), 2e-5f) << degrees;
    EXPECT_LT(circle.rmse, 1e-5f) << degrees;
  }
}

struct ArcStatistics {
  double algebraic_bias = 0, refined_bias = 0;    // mean (fit - truth)
  double algebraic_worst = 0, refined_worst = 0;  // max |fit - truth|
  double refined_rms = 0;                         // RMS (fit - truth)
  int refined_better = 0;  // trials where the refinement moved closer to the truth
};

ArcStatistics arcStatistics(float degrees, float sigma, int trials, bool along_ray = false) {
  ArcStatistics stats;
  const float radius = 0.04f;
  for (int seed = 1; seed <= trials; ++seed) {
    const auto points =
        arc(Eigen::Vector2f(0.3f, 0.9f), radius, degrees, 200, sigma, seed, along_ray);
    const Circle algebraic = fitCircleAlgebraic(points);
    const Circle refined = refineCircleGeometric(points, algebraic, 50);
    EXPECT_TRUE(algebraic.ok && refined.ok);
    const double a = algebraic.radius - radius, r = refined.radius - radius;
    stats.algebraic_bias += a / trials;
    stats.refined_bias += r / trials;
    stats.algebraic_worst = std::max(stats.algebraic_worst, std::abs(a));
    stats.refined_worst = std::max(stats.refined_worst, std::abs(r));
    stats.refined_rms += r * r / trials;
    stats.refined_better += std::abs(r) < std::abs(a);
    // The geometric refinement minimises the RMS geometric residual: never worse than its start.
    EXPECT_LE(refined.rmse, algebraic.rmse + 1e-7f);
  }
  stats.refined_rms = std::sqrt(stats.refined_rms);
  std::printf(
      "arc %3.0f deg sigma %.0f mm %s: radius bias algebraic %+.2f mm (worst %.2f), "
      "refined %+.2f mm (rms %.2f, worst %.2f), refined closer in %d/%d\n",
      degrees, sigma * 1e3, along_ray ? "ray noise " : "isotropic", stats.algebraic_bias * 1e3,
      stats.algebraic_worst * 1e3, stats.refined_bias * 1e3, stats.refined_rms * 1e3,
      stats.refined_worst * 1e3, stats.refined_better, trials);
  return stats;
}

TEST(CircleFit, RefinementRemovesTheShortArcBias) {
  const int trials = 100;
  // 180 degrees (the most a camera sees of a can), sigma 1 mm: both good, refined within 1 mm.
  const ArcStatistics half = arcStatistics(180.0f, 0.001f, trials);
  EXPECT_LT(half.refined_worst, 0.001);
  EXPECT_LT(std::abs(half.refined_bias), 0.0002);
  // 90 degrees, sigma 1 mm: the algebraic fit shrinks the circle; the refinement does not.
  const ArcStatistics quarter = arcStatistics(90.0f, 0.001f, trials);
  EXPECT_LT(quarter.algebraic_bias, -0.001);
  EXPECT_LT(std::abs(quarter.refined_bias), 0.0003);
  EXPECT_LT(quarter.refined_rms, 0.001);
  EXPECT_LT(quarter.refined_worst, 0.003);
  EXPECT_GT(quarter.refined_better, trials * 3 / 4);
  // 3 mm noise: reported for the record, the refinement still removes most of the bias.
  const ArcStatistics half3 = arcStatistics(180.0f, 0.003f, trials);
  const ArcStatistics quarter3 = arcStatistics(90.0f, 0.003f, trials);
  EXPECT_LT(std::abs(half3.refined_bias), 0.0005);
  EXPECT_LT(std::abs(quarter3.refined_bias), std::abs(quarter3.algebraic_bias) / 2);
  // Depth noise only (along the camera's rays, here x): at the arc's ends it is half radial,
  // half tangential, and the two parts are correlated (a point pushed outwards also slides
  // towards the middle), which bends the arc's ends in: the geometric fit is biased low, by
  // ~sigma^2 / 2.7 mm on a 90 degree arc (-0.4 mm at 1 mm, -3.3 mm at 3 mm), negligible on
  // 180 degrees (-0.2 mm at 3 mm). It is the least-squares minimum, not a convergence issue.
  const ArcStatistics ray_half = arcStatistics(180.0f, 0.003f, trials, true);
  EXPECT_LT(std::abs(ray_half.refined_bias), 0.0003);
  const ArcStatistics ray_quarter = arcStatistics(90.0f, 0.001f, trials, true);
  EXPECT_LT(std::abs(ray_quarter.refined_bias), 0.0006);
  EXPECT_LT(ray_quarter.refined_rms, 0.001);
  const ArcStatistics ray_quarter3 = arcStatistics(90.0f, 0.003f, trials, true);
  EXPECT_LT(std::abs(ray_quarter3.refined_bias), std::abs(ray_quarter3.algebraic_bias) / 3);
}

// Levenberg-Marquardt sums its normal equations over lanes of points (two or four): every
// count of points, whole lanes or not, reaches the exact circle from a start millimetres off.
TEST(CircleFit, RefinementFindsAnExactCircleWhateverThePointsLeftOverFromTheLanes) {
  const Eigen::Vector2f centre(0.3f, -0.2f);
  const float radius = 0.04f;
  for (int n = 3; n <= 11; ++n) {
    std::vector<Eigen::Vector2f> points;
    for (int i = 0; i < n; ++i) {
      const float angle = 2.1f * static_cast<float>(i) / static_cast<float>(n - 1);  // 120 degrees
      points.push_back(centre + radius * Eigen::Vector2f(std::cos(angle), std::sin(angle)));
    }
    Circle start;
    start.center = centre + Eigen::Vector2f(0.003f, -0.002f);
    start.radius = radius + 0.004f;
    start.ok = true;
    const Circle refined = refineCircleGeometric(points, start, 100);
    ASSERT_TRUE(refined.ok) << n << " points";
    EXPECT_LT((refined.center - centre).norm(), 2e-6f) << n << " points";
    EXPECT_NEAR(refined.radius, radius, 2e-6f) << n << " points";
    EXPECT_LT(refined.rmse, 1e-6f) << n << " points";
  }
}

TEST(CircleFit, DegenerateInputIsRejected) {
  EXPECT_FALSE(fitCircleAlgebraic({}).ok);
  EXPECT_FALSE(fitCircleAlgebraic({{0.0f, 0.0f}, {1.0f, 1.0f}}).ok);
  EXPECT_FALSE(fitCircleAlgebraic({{0.0f, 0.0f}, {0.1f, 0.2f}, {0.2f, 0.4f}, {0.3f, 0.6f}}).ok);
  EXPECT_FALSE(fitCircleAlgebraic({{0.1f, 0.1f}, {0.1f, 0.1f}, {0.1f, 0.1f}}).ok);
  EXPECT_FALSE(refineCircleGeometric({{0.0f, 0.0f}, {1.0f, 1.0f}}, Circle{}, 50).ok);
  // Three points define a circle exactly.
  const Circle three = fitCircleAlgebraic({{1.0f, 0.0f}, {0.0f, 1.0f}, {-1.0f, 0.0f}});
  ASSERT_TRUE(three.ok);
  EXPECT_NEAR(three.radius, 1.0f, 1e-5f);
}

// ---- cylinder and cone on synthetic objects ----

void expectMug(const ShapeFit& fit, const Scene& scene, const char* what) {
  ASSERT_TRUE(fit.ok) << what << ": " << fit.reason;
  EXPECT_EQ(fit.type, ShapeType::Cylinder) << what;
  EXPECT_NEAR(fit.radius, kMugRadius, 0.02f * kMugRadius) << what;
  EXPECT_NEAR(fit.height, kMugHeight, 0.02f * kMugHeight) << what;
  EXPECT_LT((fit.center - trueCentre(scene, kMugHeight)).norm(), 0.005f) << what;
  EXPECT_GT(fit.axis().dot(scene.table.normal), std::cos(degToRad(0.5f))) << what;
  EXPECT_GT(fit.points, 100) << what;
  EXPECT_LT(fit.rmse, 0.004f) << what;
}

TEST(CylinderFit, PaperMugFromAKinectViewpoint) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const Scene scene = roundScene(kMugRadius, kMugRadius, kMugHeight, seed, false);
    const ShapeFit fit = fitCylinder(scene.object, scene.table, CylinderParams{});
    std::printf("mug seed %u: r %.2f mm h %.2f mm centre err %.2f mm rmse %.2f mm, %d pts\n", seed,
                fit.radius * 1e3, fit.height * 1e3,
                (fit.center - trueCentre(scene, kMugHeight)).norm() * 1e3, fit.rmse * 1e3,
                fit.points);
    expectMug(fit, scene, "fitCylinder");
    expectMug(fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{}), scene,
              "fitRoundObject");
  }
}

TEST(CylinderFit, PaperMugFromBelowItsTop) {
  // Camera at 0.1 m, below the mug's top: no top disc, the height comes from the side wall.
  const Scene scene = roundScene(kMugRadius, kMugRadius, kMugHeight, 6, false, 0.002f, false, 0.1f);
  const ShapeFit fit = fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{});
  std::printf("mug from below its top: r %.2f mm h %.2f mm\n", fit.radius * 1e3, fit.height * 1e3);
  expectMug(fit, scene, "low camera");
}

TEST(CylinderFit, PaperMugWithMlsNormals) {
  const Scene scene = roundScene(kMugRadius, kMugRadius, kMugHeight, 4, true);
  const ShapeFit fit = fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{});
  std::printf("mug (MLS normals): r %.2f mm h %.2f mm centre err %.2f mm\n", fit.radius * 1e3,
              fit.height * 1e3, (fit.center - trueCentre(scene, kMugHeight)).norm() * 1e3);
  expectMug(fit, scene, "MLS");
}

TEST(CylinderFit, TrimmingIgnoresTheMugsHandle) {
  const Scene scene = roundScene(kMugRadius, kMugRadius, kMugHeight, 5, false, 0.002f, true);
  const ShapeFit fit = fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{});
  expectMug(fit, scene, "handle");
  // Plain least squares on the same side-wall points (table frame, below the rim) is pulled
  // towards the handle.
  std::vector<Eigen::Vector2f> side;
  const Eigen::Isometry3f camera_to_table = scene.table_to_camera.inverse();
  for (const auto& p : scene.object.points) {
    const Eigen::Vector3f q = camera_to_table * p.getVector3fMap();
    const Eigen::Vector3f n = camera_to_table.linear() * p.getNormalVector3fMap();
    if (std::abs(n.z()) < 0.7f && q.z() < kMugHeight - 0.01f) side.push_back(q.head<2>());
  }
  const Circle plain = refineCircleGeometric(side, fitCircleAlgebraic(side), 50);
  ASSERT_TRUE(plain.ok);
  std::printf(
      "mug with handle: radius trimmed %.2f mm, plain least squares %.2f mm (%d of %zu "
      "side points kept)\n",
      fit.radius * 1e3, plain.radius * 1e3, fit.points, side.size());
  EXPECT_LT(std::abs(fit.radius - kMugRadius), std::abs(plain.radius - kMugRadius) / 2);
  EXPECT_LT(fit.points, static_cast<int>(side.size()) - 60);  // the handle's 84 points mostly
}

void expectBeaker(const ShapeFit& fit, const Scene& scene, const char* what) {
  ASSERT_TRUE(fit.ok) << what << ": " << fit.reason;
  EXPECT_EQ(fit.type, ShapeType::Cone) << what;
  EXPECT_NEAR(fit.radius_bottom, kBeakerBottom, 0.0015f) << what;
  EXPECT_NEAR(fit.radius_top, kBeakerTop, 0.0015f) << what;
  EXPECT_NEAR(fit.height, kBeakerHeight, 0.02f * kBeakerHeight) << what;
  EXPECT_LT((fit.center - trueCentre(scene, kBeakerHeight)).norm(), 0.005f) << what;
  EXPECT_GT(fit.axis().dot(scene.table.normal), std::cos(degToRad(0.5f))) << what;
}

TEST(ConeFit, PaperBeakerIsACone) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const Scene scene = roundScene(kBeakerBottom, kBeakerTop, kBeakerHeight, seed, false);
    const ShapeFit cone = fitCone(scene.object, scene.table, CylinderParams{}, ConeParams{});
    const ShapeFit cylinder = fitCylinder(scene.object, scene.table, CylinderParams{});
    std::printf("beaker seed %u: r %.2f-%.2f mm h %.2f mm rmse cone %.2f mm cylinder %.2f mm\n",
                seed, cone.radius_bottom * 1e3, cone.radius_top * 1e3, cone.height * 1e3,
                cone.rmse * 1e3, cylinder.rmse * 1e3);
    expectBeaker(cone, scene, "fitCone");
    EXPECT_LT(cone.rmse, cylinder.rmse);
    expectBeaker(fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{}), scene,
                 "fitRoundObject");
  }
}

TEST(ConeFit, PaperBeakerWithMlsNormals) {
  const Scene scene = roundScene(kBeakerBottom, kBeakerTop, kBeakerHeight, 4, true);
  expectBeaker(fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{}), scene,
               "MLS");
}

TEST(ConeFit, NoisyCylindersAreNotCones) {
  // Several seeds, radii, heights and noise levels: a false cone would mislead the grasp.
  int cones = 0, trials = 0;
  double largest_slope = 0.0;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    for (float radius : {0.03f, 0.05f}) {
      const float height = seed % 2 ? 0.12f : 0.08f;
      const Scene scene = roundScene(radius, radius, height, seed, false, 0.003f);
      const ShapeFit fit =
          fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{});
      const ShapeFit cone = fitCone(scene.object, scene.table, CylinderParams{}, ConeParams{});
      ASSERT_TRUE(fit.ok) << fit.reason;
      ++trials;
      cones += fit.type == ShapeType::Cone;
      largest_slope = std::max(
          largest_slope, std::abs(double(cone.radius_top - cone.radius_bottom)) / cone.height);
      EXPECT_EQ(fit.type, ShapeType::Cylinder) << "seed " << seed << " r " << radius;
      EXPECT_NEAR(fit.radius, radius, 0.02f * radius);
    }
  }
  std::printf("noisy cylinders called cones: %d/%d, largest fitted |slope| %.4f\n", cones, trials,
              largest_slope);
}

TEST(ConeFit, BowlTaperOpensUpward) {
  // A bowl seen over its rim: the outer wall facing the camera and the inside of the far wall.
  // Points low on the near wall and high on the far wall let a fit trade the centre against
  // the slope; a real bowl's cone came out upside down that way. Its taper is what its near wall
  // shows: the radius grows upwards.
  const float r_bottom = 0.045f, r_top = 0.075f, height = 0.06f;
  for (float camera_height : {0.4f, 0.6f}) {
    for (unsigned seed : {1u, 2u}) {
      Sampler sampler = synthetic::voxelGridSampler();
      sampler.camera.z() = camera_height;
      sampler.seed = seed;
      CloudPtr cloud = synthetic::bowl(r_bottom, r_top, height, 0.004f, kObjectCentre, sampler);
      const Eigen::Isometry3f to_camera = tableToCamera(
          sampler.camera, Eigen::Vector3f(kObjectCentre.x(), kObjectCentre.y(), height / 2));
      synthetic::transformCloud(to_camera, *cloud);
      const Plane table = synthetic::transformPlane(to_camera, synthetic::tablePlane());
      NormalCloud object;
      estimateNormalsMLS(cloud, NormalParams{}, object);
      const ShapeFit fit = fitRoundObject(object, table, CylinderParams{}, ConeParams{});
      std::printf("bowl camera %.1f m up, seed %u: %s r %.1f-%.1f mm h %.1f mm\n", camera_height,
                  seed, shapeTypeName(fit.type), fit.radius_bottom * 1e3, fit.radius_top * 1e3,
                  fit.height * 1e3);
      ASSERT_TRUE(fit.ok) << fit.reason;
      ASSERT_EQ(fit.type, ShapeType::Cone);
      EXPECT_GT(fit.radius_top, fit.radius_bottom + 0.01f);
      EXPECT_NEAR(fit.radius_top, r_top, 0.006f);
      EXPECT_NEAR(fit.height, height, 0.005f);
    }
  }
}

TEST(CylinderFit, OpenMugIsMeasuredOnItsOuterWall) {
  // A mug seen over its rim: the outer wall facing the camera and the far inner wall, a wall's
  // thickness (4 mm) inside it. One circle through both came out 2 mm (5 %) small on every
  // rendered mug; the inner wall gets its own concentric circle, and the radius is the outer one.
  const float radius = 0.041f, height = 0.095f, wall = 0.004f;
  for (float camera_height : {0.4f, 0.6f}) {
    for (unsigned seed : {1u, 2u}) {
      Sampler sampler = synthetic::voxelGridSampler();
      sampler.camera.z() = camera_height;
      sampler.seed = seed;
      CloudPtr cloud = synthetic::bowl(radius, radius, height, wall, kObjectCentre, sampler);
      const Eigen::Isometry3f to_camera = tableToCamera(
          sampler.camera, Eigen::Vector3f(kObjectCentre.x(), kObjectCentre.y(), height / 2));
      synthetic::transformCloud(to_camera, *cloud);
      const Plane table = synthetic::transformPlane(to_camera, synthetic::tablePlane());
      NormalCloud object;
      estimateNormalsMLS(cloud, NormalParams{}, object);
      const ShapeFit fit = fitRoundObject(object, table, CylinderParams{}, ConeParams{});
      std::printf("open mug camera %.1f m up, seed %u: %s r %.2f mm h %.1f mm\n", camera_height,
                  seed, shapeTypeName(fit.type), fit.radius * 1e3, fit.height * 1e3);
      ASSERT_TRUE(fit.ok) << fit.reason;
      EXPECT_EQ(fit.type, ShapeType::Cylinder);
      EXPECT_NEAR(fit.radius, radius, 0.0008f);  // half a wall or more off without the rule
      EXPECT_NEAR(fit.height, height, 0.004f);
      const Eigen::Vector3f centre =
          to_camera * Eigen::Vector3f(kObjectCentre.x(), kObjectCentre.y(), height / 2);
      EXPECT_LT((fit.center - centre).norm(), 0.0015f);
    }
  }
}

// A bottle as the renderer builds one: body to 60 % of the height, a shoulder narrowing to the
// neck (0.35 of the radius, at least 11 mm) up to 77 %, neck and cap to the top. Its visible
// surface in the table frame.
CloudPtr bottle(float radius, float height, const Sampler& s) {
  std::mt19937 rng(s.seed);
  auto out = std::make_shared<Cloud>();
  const float neck = std::max(0.35f * radius, 0.011f);
  const float shoulder_bottom = 0.6f * height, shoulder_top = 0.77f * height;
  const float shoulder_slope = (neck - radius) / (shoulder_top - shoulder_bottom);
  for (float z = 0.0f; z <= height + 1e-6f; z += s.spacing) {
    const bool on_shoulder = z > shoulder_bottom && z < shoulder_top;
    const float r = z <= shoulder_bottom ? radius
                    : on_shoulder        ? radius + shoulder_slope * (z - shoulder_bottom)
                                         : neck;
    const float slope = on_shoulder ? shoulder_slope : 0.0f;
    const int steps = std::max(8, static_cast<int>(2 * kPi * r / s.spacing));
    for (int i = 0; i < steps; ++i) {
      const float t = static_cast<float>(2 * kPi * i / steps);
      const Eigen::Vector3f p(kObjectCentre.x() + r * std::cos(t),
                              kObjectCentre.y() + r * std::sin(t), z);
      synthetic::addIfVisible(p, Eigen::Vector3f(std::cos(t), std::sin(t), -slope).normalized(), s,
                              rng, *out);
    }
  }
  for (float rr = 0.0f; rr <= neck; rr += s.spacing) {
    const int steps = std::max(1, static_cast<int>(2 * kPi * rr / s.spacing));
    for (int i = 0; i < steps; ++i) {
      const float t = static_cast<float>(2 * kPi * i / steps);
      synthetic::addIfVisible(
          {kObjectCentre.x() + rr * std::cos(t), kObjectCentre.y() + rr * std::sin(t), height},
          Eigen::Vector3f::UnitZ(), s, rng, *out);
    }
  }
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  return out;
}

TEST(RoundObject, BottleIsACylinderWithItsBodysRadius) {
  // A cone through body, shoulder and neck came out 25-45 % wider than the body at the bottom
  // on rendered bottles; a bottle counts as the cylinder of its body, as tall as its cap.
  for (const auto& [radius, height] : {std::pair{0.0325f, 0.205f}, std::pair{0.04f, 0.26f}}) {
    for (float camera_height : {0.6f, 1.0f}) {
      for (unsigned seed : {1u, 2u}) {
        const Sampler sampler = roundSampler(seed, camera_height);
        CloudPtr cloud = bottle(radius, height, sampler);
        addRayNoise(sampler.camera, 0.002f, seed, *cloud);
        Scene scene = sceneFor(sampler, height);
        withMlsNormals(cloud, scene);
        const ShapeFit fit =
            fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{});
        std::printf(
            "bottle r %.1f mm h %.0f mm, camera %.1f m up, seed %u: %s r %.1f-%.1f mm h %.1f mm\n",
            radius * 1e3, height * 1e3, camera_height, seed, shapeTypeName(fit.type),
            (fit.type == ShapeType::Cone ? fit.radius_bottom : fit.radius) * 1e3,
            (fit.type == ShapeType::Cone ? fit.radius_top : fit.radius) * 1e3, fit.height * 1e3);
        ASSERT_TRUE(fit.ok) << fit.reason;
        EXPECT_EQ(fit.type, ShapeType::Cylinder);
        EXPECT_NEAR(fit.radius, radius, 0.003f);
        EXPECT_NEAR(fit.height, height, 0.005f);
      }
    }
  }
}

TEST(RoundObject, ShortWideCanIsACylinder) {
  // 85 mm across, 33 mm tall: between the table band and the rim band only ~15 mm of its wall
  // is left for the slope.
  const float radius = 0.0425f, height = 0.033f;
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const Scene scene = roundScene(radius, radius, height, seed, true);
    const ShapeFit fit = fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{});
    ASSERT_TRUE(fit.ok) << fit.reason;
    EXPECT_EQ(fit.type, ShapeType::Cylinder)
        << "seed " << seed << ": r " << fit.radius_bottom << "-" << fit.radius_top;
    EXPECT_NEAR(fit.radius, radius, 0.002f);
    EXPECT_NEAR(fit.height, height, 0.002f);
  }
}

TEST(RoundObject, StraightConeNarrowingUpwardsIsStillACone) {
  // The bottle rule takes only tapers that are not straight: a lamp shade stays a cone.
  const float r_bottom = 0.05f, r_top = 0.03f, height = 0.15f;
  for (unsigned seed : {1u, 2u}) {
    const Scene scene = roundScene(r_bottom, r_top, height, seed, true);
    const ShapeFit fit = fitRoundObject(scene.object, scene.table, CylinderParams{}, ConeParams{});
    ASSERT_TRUE(fit.ok) << fit.reason;
    ASSERT_EQ(fit.type, ShapeType::Cone);
    EXPECT_NEAR(fit.radius_bottom, r_bottom, 0.002f);
    EXPECT_NEAR(fit.radius_top, r_top, 0.002f);
  }
}

// ---- bad input ----

// The visible surface of an upright cylinder (r 0.1 m, 0.2 m tall, axis along z, the camera at
// the origin 1 m away at mid-height): the wall within acos(r / 1 m) of the camera's azimuth
// (84.3 degrees) faces it; a point beyond is as far as the nearer silhouette generatrix. Points
// 1 cm out of the wall all round (every half degree, and each silhouette's azimuth and 1e-9 rad
// either side of it), and on the axis (no azimuth: the negative side's generatrix, r away).
TEST(VisibleRoundSurface, TheWallFacingTheCameraAndTheNearerSilhouetteBeyond) {
  ShapeFit round;
  round.type = ShapeType::Cylinder;
  round.center = Eigen::Vector3f(1.0f, 0.0f, 0.0f);
  round.radius = 0.1f;
  round.height = 0.2f;
  const double camera_azimuth = kPi, half_angle = std::acos(0.1);
  std::vector<double> azimuths;
  for (int step = 0; step < 720; ++step) azimuths.push_back(degToRad(0.5 * step));
  for (double side : {-1.0, 1.0}) {
    for (double off : {-1e-9, 0.0, 1e-9}) {
      azimuths.push_back(camera_azimuth + side * half_angle + off);
    }
  }
  for (double azimuth : azimuths) {
    const double rho = 0.11;
    const Eigen::Vector3f point =
        round.center +
        Eigen::Vector3d(rho * std::cos(azimuth), rho * std::sin(azimuth), 0.0).cast<float>();
    const double offset = std::remainder(azimuth - camera_azimuth, 2.0 * kPi);
    double expected = 0.01;
    if (std::abs(offset) > half_angle + 1e-6) {
      const double silhouette = camera_azimuth + std::copysign(half_angle, offset);
      expected = (Eigen::Vector2d(rho * std::cos(azimuth), rho * std::sin(azimuth)) -
                  0.1 * Eigen::Vector2d(std::cos(silhouette), std::sin(silhouette)))
                     .norm();
    } else if (std::abs(offset) > half_angle - 1e-6) {
      expected = std::numeric_limits<double>::quiet_NaN();  // either: within 1e-7 of 0.01
    }
    const float distance = distanceToVisibleRoundSurface(round, point);
    if (std::isnan(expected)) {
      EXPECT_NEAR(distance, 0.01, 1e-5) << "azimuth " << azimuth;
    } else {
      EXPECT_NEAR(distance, expected, 1e-5) << "azimuth " << azimuth;
    }
  }
  // On the axis: atan2(0, 0) - pi, offset -pi, the generatrix at pi - 84.3 degrees, r away.
  EXPECT_NEAR(distanceToVisibleRoundSurface(round, round.center), 0.1, 1e-6);
}

TEST(CylinderFit, BadInputFailsWithAReason) {
  const Plane table = synthetic::tablePlane();
  const auto expectFailure = [&](const NormalCloud& cloud, const char* what) {
    for (const ShapeFit& fit : {fitCylinder(cloud, table, CylinderParams{}),
                                fitCone(cloud, table, CylinderParams{}, ConeParams{}),
                                fitRoundObject(cloud, table, CylinderParams{}, ConeParams{})}) {
      EXPECT_FALSE(fit.ok) << what << " " << shapeTypeName(fit.type);
      EXPECT_FALSE(fit.reason.empty()) << what;
    }
  };
  const auto point = [](float x, float y, float z, const Eigen::Vector3f& n) {
    pcl::PointNormal p;
    p.getVector3fMap() = Eigen::Vector3f(x, y, z);
    p.getNormalVector3fMap() = n;
    return p;
  };
  const Eigen::Vector3f side(0.0f, -1.0f, 0.0f);

  NormalCloud empty;
  expectFailure(empty, "empty");

  NormalCloud two;
  two.push_back(point(0.0f, 0.0f, 0.05f, side));
  two.push_back(point(0.01f, 0.0f, 0.06f, side));
  expectFailure(two, "two points");

  NormalCloud all_nan;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int i = 0; i < 50; ++i) all_nan.push_back(point(nan, nan, nan, side));
  expectFailure(all_nan, "all NaN");

  // A vertical wall (a box face): collinear in the table plane, with and without noise.
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.001f);
  NormalCloud wall, noisy_wall;
  for (float x = -0.05f; x <= 0.05f; x += 0.004f) {
    for (float z = 0.01f; z <= 0.1f; z += 0.004f) {
      wall.push_back(point(x, 0.0f, z, side));
      noisy_wall.push_back(point(x, noise(rng), z, side));
    }
  }
  expectFailure(wall, "vertical wall");
  expectFailure(noisy_wall, "noisy vertical wall");

  // A flat patch parallel to the table (a sheet of paper, a tray's bottom): no side wall.
  NormalCloud flat;
  for (float x = -0.05f; x <= 0.05f; x += 0.004f) {
    for (float y = -0.05f; y <= 0.05f; y += 0.004f) {
      flat.push_back(point(x, y, 0.01f, Eigen::Vector3f::UnitZ()));
    }
  }
  expectFailure(flat, "flat patch");

  // Radius bounds: a 0.5 m drum is outside max_radius = 0.3 m.
  Sampler sampler;
  sampler.spacing = 0.01f;
  sampler.camera = Eigen::Vector3f(0.0f, -3.0f, 1.5f);
  const NormalCloud drum =
      analyticNormals(*synthetic::roundObject(0.5f, 0.5f, 0.2f, Eigen::Vector2f::Zero(), sampler),
                      0.5f, 0.5f, 0.2f, Eigen::Vector2f::Zero());
  const ShapeFit fit = fitCylinder(drum, table, CylinderParams{});
  EXPECT_FALSE(fit.ok);
  EXPECT_NE(fit.reason.find("radius"), std::string::npos) << fit.reason;
  EXPECT_NEAR(fit.radius, 0.5f, 0.005f);  // measured right, rejected by the bound
}

}  // namespace
}  // namespace tabletop_shapes
