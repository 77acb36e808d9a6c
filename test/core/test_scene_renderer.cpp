// Known-answer tests of the rendered-scene generator: exact geometry when noiseless, the
// documented noise statistics, determinism, valid random layouts, and the written files.
#include "tabletop_shapes/sim/evaluation.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <cstdio>
#include <map>

namespace tabletop_shapes {
namespace sim {
namespace {

// Distance from p to the surface of the box |x_i| <= half_i (local frame).
float boxSurfaceDistance(const Eigen::Vector3f& p, const Eigen::Vector3f& half) {
  const Eigen::Vector3f outside = (p.cwiseAbs() - half).cwiseMax(0.0f);
  if (outside.squaredNorm() > 0) return outside.norm();
  return (half - p.cwiseAbs()).minCoeff();
}

// Distance from p (local frame: bottom centre, z up) to a truncated cone's side or caps.
float roundSurfaceDistance(const Eigen::Vector3f& p, float r_bottom, float r_top, float height) {
  const float slope = (r_top - r_bottom) / height;
  const float radial = p.head<2>().norm();
  float best = std::numeric_limits<float>::infinity();
  if (p.z() >= 0 && p.z() <= height) {
    best = std::abs(radial - (r_bottom + slope * p.z())) / std::sqrt(1 + slope * slope);
  }
  if (radial <= r_top) best = std::min(best, std::abs(p.z() - height));
  if (radial <= r_bottom) best = std::min(best, std::abs(p.z()));
  return best;
}

// Distance of a world point to the surface with the given label.
float surfaceDistance(const SceneSpec& spec, int label, const Eigen::Vector3f& world) {
  const TableSpec& table = spec.table;
  if (label == kFloorLabel) return std::abs(world.z());
  if (label == kTableLabel) {
    return boxSurfaceDistance(world - Eigen::Vector3f(0, 0, table.height - table.thickness / 2),
                              Eigen::Vector3f(table.length, table.width, table.thickness) / 2);
  }
  const ObjectSpec& object = spec.objects.at(label);
  const Eigen::Vector3f bottom(object.position_on_table.x(), object.position_on_table.y(),
                               table.height);
  const Eigen::Vector3f local =
      Eigen::AngleAxisf(-object.yaw, Eigen::Vector3f::UnitZ()) * (world - bottom);
  if (object.type == ShapeType::Cube) {
    return boxSurfaceDistance(local - Eigen::Vector3f(0, 0, object.box_size.z() / 2),
                              object.box_size / 2);
  }
  const float r_top = object.type == ShapeType::Cone ? object.radius_top : object.radius_bottom;
  return roundSurfaceDistance(local, object.radius_bottom, r_top, object.height);
}

SceneSpec singleObjectScene(const ObjectSpec& object) {
  SceneSpec spec;
  spec.objects.push_back(object);
  spec.objects[0].position_on_table = {0.05f, -0.03f};
  spec.objects[0].yaw = degToRad(30.0f);
  spec.placement = {1.0f, 40.0f, 70.0f};
  spec.noise = NoiseModel::noiseless();
  return spec;
}

// Every valid pixel lies on the surface it is labelled with, to 0.1 mm, for each solid type.
TEST(SceneRenderer, NoiselessPointsLieOnTheirSurfaces) {
  for (const ObjectSpec& object : {teapotBox(), steelMug(), beaker()}) {
    const SceneSpec spec = singleObjectScene(object);
    const RenderedScene scene = renderScene(spec);
    ASSERT_EQ(scene.cloud->width, 640u);
    ASSERT_EQ(scene.cloud->height, 480u);
    std::map<int, int> counts;
    float worst = 0.0f;
    for (size_t i = 0; i < scene.cloud->size(); ++i) {
      const auto& p = scene.cloud->points[i];
      const int label = scene.labels[i];
      if (!std::isfinite(p.z)) {
        EXPECT_EQ(label, kNoReturn);
        continue;
      }
      ASSERT_NE(label, kNoReturn);
      ++counts[label];
      const Eigen::Vector3f world = scene.world_from_camera * p.getVector3fMap();
      worst = std::max(worst, surfaceDistance(spec, label, world));
    }
    EXPECT_LT(worst, 1e-4f) << object.name;
    EXPECT_GT(counts[0], 3000) << object.name;  // the object at 1 m
    EXPECT_GT(counts[kTableLabel], 100000) << object.name;
    EXPECT_EQ(scene.objects[0].visible_pixels, counts[0]);
  }
}

// The principal ray passes through the look-at point: known depth on the table, a box top and
// a cylinder top (camera looking straight down).
TEST(SceneRenderer, PrincipalRayHitsKnownDepth) {
  SceneSpec spec;
  spec.camera.cx = 320.0f;
  spec.camera.cy = 240.0f;
  spec.noise = NoiseModel::noiseless();
  const size_t centre = 240 * 640 + 320;

  spec.placement = {1.1f, 35.0f, 120.0f};  // no objects: looks at the table centre
  RenderedScene scene = renderScene(spec);
  EXPECT_EQ(scene.labels[centre], kTableLabel);
  EXPECT_NEAR(scene.cloud->points[centre].z, 1.1f, 1e-5f);
  EXPECT_NEAR(scene.cloud->points[centre].x, 0.0f, 1e-6f);
  EXPECT_NEAR(scene.cloud->points[centre].y, 0.0f, 1e-6f);

  spec.placement = {1.0f, 90.0f, 0.0f};
  spec.objects = {teapotBox()};  // height 0.10
  scene = renderScene(spec);
  EXPECT_EQ(scene.labels[centre], 0);
  EXPECT_NEAR(scene.cloud->points[centre].z, 0.90f, 1e-5f);

  spec.objects = {steelMug()};  // height 0.16
  spec.objects[0].position_on_table = {-0.2f, 0.1f};
  scene = renderScene(spec);
  EXPECT_EQ(scene.labels[centre], 0);
  EXPECT_NEAR(scene.cloud->points[centre].z, 0.84f, 1e-5f);
  // Looking straight down, the ground truth centre lies on the principal ray at mid-height.
  EXPECT_NEAR(scene.objects[0].center.x(), 0.0f, 1e-5f);
  EXPECT_NEAR(scene.objects[0].center.y(), 0.0f, 1e-5f);
  EXPECT_NEAR(scene.objects[0].center.z(), 0.92f, 1e-5f);
  EXPECT_NEAR(scene.objects[0].axis().z(), -1.0f, 1e-5f);  // up = towards the camera
}

// The ground-truth plane is the one the rendered (noisy) table top points lie on, and the
// ground-truth objects stand on it.
TEST(SceneRenderer, GroundTruthPlaneMatchesTablePoints) {
  const RenderedScene scene = renderScene(paperScene({1.2f, 50.0f, 100.0f}));
  // Least-squares plane through the table-top points (the top face: within 2 cm of the plane,
  // which leaves out the 3 cm edge faces), mean-centred.
  std::vector<Eigen::Vector3f> points;
  for (size_t i = 0; i < scene.cloud->size(); ++i) {
    const Eigen::Vector3f p = scene.cloud->points[i].getVector3fMap();
    if (scene.labels[i] == kTableLabel && std::abs(scene.table_plane.signedDistance(p)) < 0.02f) {
      points.push_back(p);
    }
  }
  ASSERT_GT(points.size(), 50000u);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p.cast<double>();
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) {
    const Eigen::Vector3d q = p.cast<double>() - mean;
    scatter += q * q.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  Eigen::Vector3d normal = solver.eigenvectors().col(0);  // smallest eigenvalue
  if (normal.dot(scene.table_plane.normal.cast<double>()) < 0) normal = -normal;
  const double angle_deg =
      std::acos(std::min(1.0, normal.dot(scene.table_plane.normal.cast<double>()))) * 180 / kPi;
  EXPECT_LT(angle_deg, 0.2);
  EXPECT_NEAR(scene.table_plane.signedDistance(mean.cast<float>()), 0.0f, 0.001f);
  EXPECT_NEAR(scene.table_plane.normal.norm(), 1.0f, 1e-6f);
  EXPECT_LT((scene.up - scene.table_plane.normal).norm(), 1e-6f);
  EXPECT_LT(scene.table_plane.normal.y(), -0.5f);  // up is image-up for a level camera
  for (const GroundTruthObject& object : scene.objects) {
    EXPECT_NEAR(scene.table_plane.signedDistance(object.center), object.height / 2, 1e-5f);
    EXPECT_LT((object.axis() - scene.up).norm(), 1e-5f);
  }
}

// Looking straight down at the table (a plane at constant depth z), the axial noise has the
// documented sigma(z), and quantised depths are exact disparity steps.
TEST(SceneRenderer, NoiseStatisticsMatchTheModel) {
  for (float range : {0.8f, 1.2f, 1.6f}) {
    SceneSpec spec;
    spec.placement = {range, 90.0f, 0.0f};
    NoiseModel axial_only = NoiseModel::noiseless();
    axial_only.enabled = true;
    axial_only.lateral_noise = axial_only.flying_pixels = axial_only.disparity_quantisation =
        axial_only.grazing_dropout = axial_only.random_dropout = false;
    spec.noise = axial_only;
    const RenderedScene scene = renderScene(spec);
    double sum = 0, sum_sq = 0;
    int n = 0;
    for (size_t i = 0; i < scene.cloud->size(); ++i) {
      if (scene.labels[i] != kTableLabel) continue;
      const double error = scene.cloud->points[i].z - range;
      sum += error;
      sum_sq += error * error;
      ++n;
    }
    ASSERT_GT(n, 100000);
    const double mean = sum / n, sigma = std::sqrt(sum_sq / n - mean * mean);
    const double expected = 0.0012 + 0.0019 * (range - 0.4) * (range - 0.4);
    EXPECT_NEAR(sigma / expected, 1.0, 0.2) << "range " << range;
    EXPECT_NEAR(mean, 0.0, 0.1 * expected) << "range " << range;

    NoiseModel quantised_only = axial_only;
    quantised_only.axial_noise = false;
    quantised_only.disparity_quantisation = true;
    spec.noise = quantised_only;
    const RenderedScene quantised = renderScene(spec);
    const double focal_baseline = spec.camera.fx * 0.075;
    const double step = range * range * 0.125 / focal_baseline;  // depth step at this range
    for (size_t i = 0; i < quantised.cloud->size(); i += 97) {
      if (quantised.labels[i] != kTableLabel) continue;
      const double z = quantised.cloud->points[i].z;
      EXPECT_LE(std::abs(z - range), step / 2 + 1e-5);
      const double disparity_steps = focal_baseline / z / 0.125;
      EXPECT_NEAR(disparity_steps, std::round(disparity_steps), 1e-3);
    }
  }
}

// Full noise: dropout near its probability, no return at grazing incidence, flying pixels
// between foreground and background at depth edges only.
TEST(SceneRenderer, FullNoiseKeepsMostObjectPixels) {
  const SceneSpec spec = paperScene({1.0f, 40.0f, 90.0f}, NoiseModel{}, 7);
  SceneSpec clean_spec = spec;
  clean_spec.noise = NoiseModel::noiseless();
  const RenderedScene noisy = renderScene(spec);
  const RenderedScene clean = renderScene(clean_spec);
  ASSERT_EQ(noisy.objects.size(), 4u);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_GT(clean.objects[k].visible_pixels, 3000) << clean.objects[k].name;
    // Dropout 1.5 % plus grazing silhouettes: at least 85 % of the pixels survive.
    EXPECT_GT(noisy.objects[k].visible_pixels, 0.85 * clean.objects[k].visible_pixels)
        << noisy.objects[k].name;
    EXPECT_LT(noisy.objects[k].visible_pixels, 0.995 * clean.objects[k].visible_pixels);
  }
  // Points of the table far from any edge stay within 5 sigma of the clean depth.
  int table_pixels = 0, lost = 0, far_off = 0;
  for (size_t i = 0; i < clean.cloud->size(); ++i) {
    if (clean.labels[i] != kTableLabel) continue;
    const int u = static_cast<int>(i % 640), v = static_cast<int>(i / 640);
    bool interior = u > 2 && v > 2 && u < 637 && v < 477;
    for (int dv = -2; dv <= 2 && interior; ++dv) {
      for (int du = -2; du <= 2 && interior; ++du) {
        interior = clean.labels[i + dv * 640 + du] == kTableLabel;
      }
    }
    if (!interior) continue;
    ++table_pixels;
    const float z_clean = clean.cloud->points[i].z, z = noisy.cloud->points[i].z;
    if (!std::isfinite(z)) {
      ++lost;
    } else {
      const float quantisation_step = z_clean * z_clean * 0.125f / (575.8f * 0.075f);
      far_off += std::abs(z - z_clean) > 5 * spec.noise.axialSigma(z_clean) + quantisation_step;
    }
  }
  ASSERT_GT(table_pixels, 100000);
  EXPECT_NEAR(static_cast<double>(lost) / table_pixels, 0.015, 0.004);
  EXPECT_LT(far_off, table_pixels / 1000);
}

TEST(SceneRenderer, FlyingPixelsLieBetweenForegroundAndBackground) {
  SceneSpec spec = singleObjectScene(teapotBox());
  NoiseModel flying_only = NoiseModel::noiseless();
  flying_only.enabled = true;
  flying_only.lateral_noise = flying_only.axial_noise = flying_only.disparity_quantisation =
      flying_only.grazing_dropout = flying_only.random_dropout = false;
  flying_only.flying_pixel_fraction = 0.5f;
  spec.noise = flying_only;
  const RenderedScene noisy = renderScene(spec);
  spec.noise = NoiseModel::noiseless();
  const RenderedScene clean = renderScene(spec);
  int moved = 0, edge_pixels = 0;
  for (int v = 1; v < 479; ++v) {
    for (int u = 1; u < 639; ++u) {
      const size_t i = static_cast<size_t>(v) * 640 + u;
      const float z = clean.cloud->points[i].z;
      if (!std::isfinite(z)) continue;
      float lo = z, hi = z;
      for (size_t j : {i - 1, i + 1, i - 640, i + 640}) {
        const float zn = clean.cloud->points[j].z;
        if (std::isfinite(zn) && std::abs(zn - z) > std::abs(hi - lo)) {
          lo = std::min(z, zn);
          hi = std::max(z, zn);
        }
      }
      const bool edge = hi - lo > flying_only.flying_min_jump;
      edge_pixels += edge;
      const float zn = noisy.cloud->points[i].z;
      if (zn != z) {
        ++moved;
        ASSERT_TRUE(edge) << u << "," << v;
        EXPECT_GE(zn, lo - 1e-6f);
        EXPECT_LE(zn, hi + 1e-6f);
      }
    }
  }
  ASSERT_GT(edge_pixels, 300);
  EXPECT_NEAR(static_cast<double>(moved) / edge_pixels, 0.5, 0.08);
}

bool sameCloud(const RenderedScene& a, const RenderedScene& b) {
  for (size_t i = 0; i < a.cloud->size(); ++i) {
    const auto &p = a.cloud->points[i], &q = b.cloud->points[i];
    const bool same = (std::isnan(p.z) && std::isnan(q.z)) ||
                      (p.x == q.x && p.y == q.y && p.z == q.z && p.rgba == q.rgba);
    if (!same) return false;
  }
  return true;
}

TEST(SceneRenderer, DeterministicWithASeed) {
  std::mt19937 rng_a(42), rng_b(42);
  const SceneSpec a = randomScene(rng_a), b = randomScene(rng_b);
  ASSERT_EQ(a.objects.size(), b.objects.size());
  EXPECT_EQ(a.seed, b.seed);
  for (size_t k = 0; k < a.objects.size(); ++k) {
    EXPECT_EQ(a.objects[k].position_on_table, b.objects[k].position_on_table);
    EXPECT_EQ(a.objects[k].yaw, b.objects[k].yaw);
  }
  const RenderedScene first = renderScene(a), second = renderScene(b);
  EXPECT_TRUE(sameCloud(first, second));
  SceneSpec other_seed = a;
  other_seed.seed = a.seed + 1;
  EXPECT_FALSE(sameCloud(first, renderScene(other_seed)));
}

// Random layouts: 1-4 objects, inside the table by the margin, not overlapping, in view.
TEST(SceneRenderer, RandomScenesAreValid) {
  std::mt19937 rng(3);
  RandomSceneOptions options;
  std::map<int, int> counts_seen;
  std::map<ShapeType, int> types_seen;
  for (int n = 0; n < 300; ++n) {
    const SceneSpec spec = randomScene(rng, options);
    const int count = static_cast<int>(spec.objects.size());
    ASSERT_GE(count, 1);
    ASSERT_LE(count, 4);
    ++counts_seen[count];
    EXPECT_GE(spec.placement.distance, 0.6f);
    EXPECT_LE(spec.placement.distance, 1.5f);
    EXPECT_GE(spec.placement.tilt_deg, 20.0f);
    EXPECT_LE(spec.placement.tilt_deg, 60.0f);
    const Eigen::Isometry3f camera_from_world = cameraPose(spec).inverse();
    for (int i = 0; i < count; ++i) {
      const ObjectSpec& a = spec.objects[i];
      ++types_seen[a.type];
      const Eigen::Vector2f extent = a.footprintHalfExtents();
      EXPECT_LE(std::abs(a.position_on_table.x()) + extent.x(), 0.6f - 0.12f + 1e-5f);
      EXPECT_LE(std::abs(a.position_on_table.y()) + extent.y(), 0.4f - 0.12f + 1e-5f);
      const Eigen::Vector3f centre =
          camera_from_world * Eigen::Vector3f(a.position_on_table.x(), a.position_on_table.y(),
                                              0.75f + a.objectHeight() / 2);
      EXPECT_GT(centre.z(), 0.45f);
      EXPECT_LT(std::abs(575.8f * centre.x() / centre.z()), 320.0f);
      EXPECT_LT(std::abs(575.8f * centre.y() / centre.z()), 240.0f);
      for (int j = 0; j < i; ++j) {
        const ObjectSpec& b = spec.objects[j];
        EXPECT_GE((a.position_on_table - b.position_on_table).norm(),
                  a.footprintRadius() + b.footprintRadius() + options.min_gap - 1e-5f);
      }
    }
  }
  EXPECT_EQ(counts_seen.size(), 4u);
  EXPECT_EQ(types_seen.size(), 3u);
}

TEST(SceneRenderer, WritesPcdAndJson) {
  const RenderedScene scene = renderScene(paperScene());
  const std::string json = groundTruthJson(scene);
  for (const char* key : {"\"cube\"", "\"cylinder\"", "\"cone\"", "\"plane\"", "\"up\"",
                          "\"sorted_dimensions\": [0.175, 0.12, 0.1]", "\"radius_top\": 0.0375"}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  int depth = 0;
  for (char c : json) depth += (c == '{' || c == '[') - (c == '}' || c == ']');
  EXPECT_EQ(depth, 0);

  const std::string path = ::testing::TempDir() + "tabletop_shapes_scene.pcd";
  ASSERT_TRUE(writePcd(scene, path));
  pcl::PointCloud<pcl::PointXYZRGB> loaded;
  ASSERT_EQ(pcl::io::loadPCDFile(path, loaded), 0);
  std::remove(path.c_str());
  EXPECT_EQ(loaded.width, 640u);
  EXPECT_EQ(loaded.height, 480u);
  RenderedScene reloaded;
  reloaded.cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>(loaded);
  EXPECT_TRUE(sameCloud(scene, reloaded));
}

// Object points in the frame of the object's ground-truth solid (centre, z = axis).
std::vector<Eigen::Vector3f> pointsInTruthFrame(const RenderedScene& scene, int label) {
  const GroundTruthObject& truth = scene.objects.at(label);
  std::vector<Eigen::Vector3f> local;
  for (size_t i = 0; i < scene.cloud->size(); ++i) {
    if (scene.labels[i] != label) continue;
    local.push_back(truth.orientation.inverse() *
                    (scene.cloud->points[i].getVector3fMap() - truth.center));
  }
  return local;
}

// Each everyday object, noiseless: its points lie inside its ground-truth solid (a mug's
// handle excepted), reach its top (the highest point is the object's height within 2 mm) and
// its width.
TEST(SceneRenderer, EverydayObjectsRenderAsTheirTruthSays) {
  for (int k = 0; k < kEverydayKinds; ++k) {
    for (int variant : {0, 1}) {
      const ObjectSpec object = everydayObject(static_cast<EverydayKind>(k), variant);
      SceneSpec spec = singleObjectScene(object);
      spec.objects[0].yaw = degToRad(-20.0f);  // a mug's handle seen from its side
      spec.placement = {0.8f, 50.0f, 70.0f};
      const RenderedScene scene = renderScene(spec);
      const GroundTruthObject& truth = scene.objects[0];
      const std::string name = object.name + " " + std::to_string(variant);
      ASSERT_GT(truth.visible_pixels, 500) << name;
      float top = 0.0f, widest = 0.0f;
      for (size_t i = 0; i < scene.cloud->size(); ++i) {
        if (scene.labels[i] != 0) continue;
        top = std::max(top,
                       scene.table_plane.signedDistance(scene.cloud->points[i].getVector3fMap()));
      }
      EXPECT_NEAR(top, object.objectHeight(), 0.002f) << name;
      const bool mug = object.form == ObjectForm::Mug;
      int outside = 0, handle = 0;
      for (const Eigen::Vector3f& p : pointsInTruthFrame(scene, 0)) {
        const float along = p.z() + truth.height / 2;  // from the solid's bottom (or end)
        if (truth.type == ShapeType::Cube) {
          outside += ((p.cwiseAbs() - truth.dimensions / 2).array() > 1e-4f).any();
          widest = std::max(widest, p.head<2>().cwiseAbs().maxCoeff());
          continue;
        }
        const float radial = p.head<2>().norm();
        const float slope = (truth.radius_top - truth.radius_bottom) / truth.height;
        const bool beyond = radial > truth.radius_bottom + slope * along + 1e-4f ||
                            std::abs(p.z()) > truth.height / 2 + 1e-4f;
        (mug ? handle : outside) += beyond;
        if (!beyond) widest = std::max(widest, radial);
      }
      EXPECT_EQ(outside, 0) << name;
      if (mug) {
        EXPECT_GT(handle, 100) << "the handle is rendered";
      }
      const float half_width = truth.type == ShapeType::Cube
                                   ? truth.dimensions.head<2>().maxCoeff() / 2
                                   : std::max(truth.radius_bottom, truth.radius_top);
      EXPECT_GT(widest, half_width - 0.003f) << name;
      if (object.form == ObjectForm::LyingCan) {
        EXPECT_NEAR(truth.axis().dot(scene.up), 0.0f, 1e-5f);
        EXPECT_NEAR(scene.table_plane.signedDistance(truth.center), object.radius_bottom, 1e-5f);
      } else {
        EXPECT_LT((truth.axis() - scene.up).norm(), 1e-5f) << name;
      }
    }
  }
}

// A bowl is hollow: seen from above, its inner floor (one wall thickness above the table,
// inside the foot) and its inner wall are visible.
TEST(SceneRenderer, BowlInsideIsVisibleFromAbove) {
  const ObjectSpec bowl = everydayObject(EverydayKind::Bowl);
  SceneSpec spec = singleObjectScene(bowl);
  spec.placement = {0.7f, 60.0f, 0.0f};
  const RenderedScene scene = renderScene(spec);
  int floor = 0, inner_wall = 0;
  const float slope = (bowl.radius_top - bowl.radius_bottom) / bowl.height;
  for (const Eigen::Vector3f& p : pointsInTruthFrame(scene, 0)) {
    const float height = p.z() + bowl.height / 2, radial = p.head<2>().norm();
    if (std::abs(height - bowl.wall_thickness) < 1e-4f && radial < bowl.radius_bottom) ++floor;
    const float inner_radius = bowl.radius_bottom + slope * height - bowl.wall_thickness;
    if (height > 0.01f && height < bowl.height - 0.001f && radial < inner_radius + 2e-4f) {
      ++inner_wall;
    }
  }
  EXPECT_GT(floor, 300);
  EXPECT_GT(inner_wall, 1000);
}

// Everyday scenes: steep views (0.5-0.7 m above the table, 40-60 deg down), objects 0.4-1.2 m
// away, and a border box centred on the image border, with pixels on it and about half of it
// out of view.
TEST(SceneRenderer, EverydayScenesHaveSteepViewsAndBorderCutBoxes) {
  int border_boxes = 0;
  for (uint32_t seed = 1; seed <= 6; ++seed) {
    for (SensorModel sensor : {SensorModel::KinectV1, SensorModel::RealSenseD435}) {
      const SceneSpec spec = everydayScene(seed, sensor);
      EXPECT_GE(spec.objects.size(), 4u) << seed;
      const float above = spec.placement.distance * std::sin(degToRad(spec.placement.tilt_deg));
      EXPECT_GE(above, 0.5f - 1e-4f);
      EXPECT_LE(above, 0.7f + 1e-4f);
      EXPECT_GE(spec.placement.tilt_deg, 40.0f);
      EXPECT_LE(spec.placement.tilt_deg, 60.0f);
      EXPECT_EQ(spec.camera.fx, sensor == SensorModel::KinectV1 ? 575.8f : 385.0f);
      const RenderedScene scene = renderScene(spec);
      for (size_t k = 0; k < scene.objects.size(); ++k) {
        const GroundTruthObject& truth = scene.objects[k];
        EXPECT_GE(truth.center.norm(), 0.4f);
        EXPECT_LE(truth.center.norm(), 1.2f);
        if (truth.name != everydayKindName(EverydayKind::BorderBox)) continue;
        ++border_boxes;
        if (truth.visible_pixels < 100) continue;  // hidden behind another object
        EXPECT_TRUE(truth.at_image_border) << seed;
        const float u = spec.camera.fx * truth.center.x() / truth.center.z() + spec.camera.cx;
        const float v = spec.camera.fy * truth.center.y() / truth.center.z() + spec.camera.cy;
        const float to_border =
            std::min({u, spec.camera.width - 1 - u, spec.camera.height - 1 - v});
        EXPECT_NEAR(to_border, 0.0f, 0.5f) << seed;
        // About half out of view: the same camera with a wider and taller image (the same
        // rays, more of them) sees about twice its pixels.
        SceneSpec wider = spec;
        wider.camera.width += 400;
        wider.camera.height += 200;
        wider.camera.cx += 200;
        const double in_view = static_cast<double>(truth.visible_pixels) /
                               renderScene(wider).objects[k].visible_pixels;
        EXPECT_GT(in_view, 0.2) << seed;
        EXPECT_LT(in_view, 0.8) << seed;
      }
    }
  }
  EXPECT_GE(border_boxes, 10);
}

// RealSense D435 noise on a flat surface facing the camera: sigma(z) = 4.16 mm * z^2 (per
// pixel and speckle together, within 20 %), and neighbouring errors are correlated by the
// speckle (~0.39: speckle variance share 0.49 times the 4/5 overlap of 5 px windows).
TEST(SceneRenderer, RealSenseNoiseGrowsWithTheSquareOfRange) {
  for (float range : {1.0f, 2.0f}) {
    SceneSpec spec;
    setSensor(spec, SensorModel::RealSenseD435);
    spec.placement = {range, 90.0f, 0.0f};
    const RenderedScene scene = renderScene(spec);
    double sum = 0, sum_sq = 0, neighbour_product = 0;
    int n = 0, pairs = 0;
    for (size_t i = 0; i + 1 < scene.cloud->size(); ++i) {
      // The middle of the table top, away from its edges' flying and bled pixels.
      const auto& p = scene.cloud->points[i];
      if (scene.labels[i] != kTableLabel || scene.labels[i + 1] != kTableLabel ||
          std::abs(p.x) > 0.35f || std::abs(p.y) > 0.35f) {
        continue;
      }
      const double error = scene.cloud->points[i].z - range;
      sum += error;
      sum_sq += error * error;
      ++n;
      neighbour_product += error * (scene.cloud->points[i + 1].z - range);
      ++pairs;
    }
    ASSERT_GT(n, 15000) << range;
    const double mean = sum / n, sigma = std::sqrt(sum_sq / n - mean * mean);
    const double expected = 0.08 * range * range / (385.0 * 0.05);
    EXPECT_NEAR(spec.noise.depthSigma(range), expected, 0.02 * expected);
    EXPECT_NEAR(sigma / expected, 1.0, 0.2) << "range " << range;
    EXPECT_NEAR(mean, 0.0, 0.1 * expected) << "range " << range;
    const double correlation = (neighbour_product / pairs - mean * mean) / (sigma * sigma);
    EXPECT_NEAR(correlation, 0.39, 0.1) << "range " << range;
  }
}

// Noise switched on with every effect off: for turning on one at a time.
NoiseModel noEffects() {
  NoiseModel model = NoiseModel::noiseless();
  model.enabled = true;
  model.lateral_noise = model.flying_pixels = model.axial_noise = model.disparity_quantisation =
      model.grazing_dropout = model.random_dropout = false;
  return model;
}

// Stereo shadow alone, looking straight down at a box (top 0.7 m, table 0.8 m away): left of
// the box top, fx * baseline * (1 / 0.7 - 1 / 0.8) = 3.4 px of table have no return, so 3 or 4
// pixels a row (the edge falls anywhere within a pixel); right of it none.
TEST(SceneRenderer, RealSenseHolesOnTheShadowSideOfDepthEdges) {
  SceneSpec spec;
  spec.objects = {teapotBox()};  // 0.10 high
  setSensor(spec, SensorModel::RealSenseD435);
  spec.placement = {0.8f, 90.0f, 0.0f};
  NoiseModel shadow_only = noEffects();
  shadow_only.baseline = 0.05f;
  shadow_only.stereo_shadow = true;
  spec.noise = shadow_only;
  const RenderedScene noisy = renderScene(spec);
  spec.noise = NoiseModel::noiseless();
  const RenderedScene clean = renderScene(spec);
  int rows = 0;
  for (int v = 0; v < 480; ++v) {
    const int* row = clean.labels.data() + v * 640;
    const int first = static_cast<int>(std::find(row, row + 640, 0) - row);
    if (first >= 640 || first < 10) continue;
    const int last = 639 - static_cast<int>(std::find(std::reverse_iterator<const int*>(row + 640),
                                                      std::reverse_iterator<const int*>(row), 0) -
                                            std::reverse_iterator<const int*>(row + 640));
    if (row[first - 5] != kTableLabel || last > 630 || row[last + 5] != kTableLabel) continue;
    ++rows;
    int holes_left = 0, holes_right = 0;
    for (int u = first - 1; u >= 0 && !std::isfinite(noisy.cloud->points[v * 640 + u].z); --u) {
      ++holes_left;
    }
    for (int u = last + 1; u < 640 && !std::isfinite(noisy.cloud->points[v * 640 + u].z); ++u) {
      ++holes_right;
    }
    EXPECT_GE(holes_left, 3) << "row " << v;
    EXPECT_LE(holes_left, 4) << "row " << v;
    EXPECT_EQ(holes_right, 0) << "row " << v;
  }
  EXPECT_GT(rows, 50);
  for (size_t i = 0; i < clean.labels.size(); ++i) {  // nothing else changed
    if (std::isfinite(noisy.cloud->points[i].z)) {
      EXPECT_EQ(noisy.cloud->points[i].z, clean.cloud->points[i].z);
    }
  }
}

// Edge bleeding alone: table pixels next to a nearer object take its depth and label, with
// probability 1, 2/3, 1/3 at 1, 2, 3 px from it, and none farther away.
TEST(SceneRenderer, RealSenseEdgeBleedingSmearsTheForeground) {
  SceneSpec spec = singleObjectScene(teapotBox());
  NoiseModel bleed_only = noEffects();
  bleed_only.edge_bleeding = true;
  bleed_only.edge_bleed_px = 3;
  spec.noise = bleed_only;
  const RenderedScene noisy = renderScene(spec);
  spec.noise = NoiseModel::noiseless();
  const RenderedScene clean = renderScene(spec);
  std::map<int, std::pair<int, int>> bled_at;  // distance -> (bled, candidates)
  for (int v = 4; v < 476; ++v) {
    for (int u = 4; u < 636; ++u) {
      const size_t i = static_cast<size_t>(v) * 640 + u;
      if (clean.labels[i] != kTableLabel) continue;
      int k_nearest = 99;  // Chebyshev distance to the nearest object pixel nearer by > 3 cm
      for (int dv = -4; dv <= 4; ++dv) {
        for (int du = -4; du <= 4; ++du) {
          const size_t j = i + dv * 640 + du;
          if (clean.labels[j] == 0 && clean.cloud->points[i].z - clean.cloud->points[j].z > 0.03f) {
            k_nearest = std::min(k_nearest, std::max(std::abs(du), std::abs(dv)));
          }
        }
      }
      const bool bled = noisy.labels[i] == 0;
      if (k_nearest > 4) continue;
      ++bled_at[k_nearest].second;
      bled_at[k_nearest].first += bled;
      if (bled) {
        EXPECT_LT(noisy.cloud->points[i].z, clean.cloud->points[i].z - 0.03f);
      }
    }
  }
  ASSERT_GT(bled_at[1].second, 200);
  EXPECT_EQ(bled_at[1].first, bled_at[1].second);
  EXPECT_NEAR(static_cast<double>(bled_at[2].first) / bled_at[2].second, 2.0 / 3, 0.08);
  EXPECT_NEAR(static_cast<double>(bled_at[3].first) / bled_at[3].second, 1.0 / 3, 0.08);
  EXPECT_EQ(bled_at[4].first, 0);
}

TEST(SceneRenderer, SensorNames) {
  SensorModel sensor = SensorModel::KinectV1;
  ASSERT_TRUE(parseSensorName("realsense", sensor));
  EXPECT_EQ(sensor, SensorModel::RealSenseD435);
  EXPECT_STREQ(sensorName(sensor), "realsense");
  ASSERT_TRUE(parseSensorName("kinect", sensor));
  EXPECT_EQ(sensor, SensorModel::KinectV1);
  EXPECT_FALSE(parseSensorName("lidar", sensor));
}

// ---- scoring everyday objects (evaluation.h): known solids, known answers ----

GroundTruthObject uprightTruth(ShapeType type, float radius_bottom, float radius_top,
                               float height) {
  GroundTruthObject truth;  // in a frame with z up
  truth.type = type;
  truth.radius_bottom = radius_bottom;
  truth.radius_top = radius_top;
  truth.height = height;
  return truth;
}

ShapeFit fittedSolid(ShapeType type, float radius_bottom, float radius_top, float height,
                     const Eigen::Quaternionf& orientation = Eigen::Quaternionf::Identity()) {
  ShapeFit fit;
  fit.ok = true;
  fit.type = type;
  fit.radius = radius_bottom;
  fit.radius_bottom = radius_bottom;
  fit.radius_top = radius_top;
  fit.height = height;
  fit.orientation = orientation;
  return fit;
}

const Eigen::Vector3f kUp = Eigen::Vector3f::UnitZ();
const Eigen::Quaternionf kAxisAlongX(Eigen::AngleAxisf(static_cast<float>(kPi / 2),
                                                       Eigen::Vector3f::UnitY()));

// The soup can typed a cone 22 % too wide, and its box cut by the border typed a
// cylinder 452 mm across: wrong solids, with their oversize.
TEST(EverydayScoring, OversizeIsTheLargestExtentRatio) {
  const GroundTruthObject can = uprightTruth(ShapeType::Cylinder, 0.033f, 0.033f, 0.101f);
  const ShapeFit cone = fittedSolid(ShapeType::Cone, 0.0403f, 0.033f, 0.095f);
  EXPECT_FALSE(expectedSolid(can, cone, kUp));
  EXPECT_NEAR(oversizePercent(can, cone, kUp), 100.0 * (0.0806 / 0.066 - 1), 0.01);
  const std::vector<Measure> extents = dimensionErrors(can, cone, kUp);
  ASSERT_EQ(extents.size(), 3u);
  EXPECT_EQ(extents[2].name, "extent height");
  EXPECT_NEAR(extents[2].error_percent, 100.0 * 0.006 / 0.101, 0.01);

  GroundTruthObject box;
  box.type = ShapeType::Cube;
  box.dimensions = {0.089f, 0.038f, 0.175f};
  const ShapeFit round = fittedSolid(ShapeType::Cylinder, 0.226f, 0.226f, 0.175f);
  EXPECT_NEAR(solidExtents(box, kUp).x(), 0.089f, 1e-6f);
  // Sorted footprints (0.452, 0.452) against (0.089, 0.038): the width is 11.9 times too large.
  EXPECT_NEAR(oversizePercent(box, round, kUp), 100.0 * (0.452 / 0.038 - 1), 0.01);

  const ShapeFit smaller = fittedSolid(ShapeType::Cylinder, 0.032f, 0.032f, 0.1f);
  EXPECT_TRUE(expectedSolid(can, smaller, kUp));
  EXPECT_LT(oversizePercent(can, smaller, kUp), 0.0);
}

// A bowl is a cone opening upward: the upside-down taper is the wrong solid.
TEST(EverydayScoring, BowlTaperMustOpenUpward) {
  const GroundTruthObject bowl = uprightTruth(ShapeType::Cone, 0.04f, 0.075f, 0.065f);
  EXPECT_TRUE(expectedSolid(bowl, fittedSolid(ShapeType::Cone, 0.045f, 0.07f, 0.065f), kUp));
  EXPECT_FALSE(expectedSolid(bowl, fittedSolid(ShapeType::Cone, 0.07f, 0.045f, 0.065f), kUp));
  EXPECT_FALSE(expectedSolid(bowl, fittedSolid(ShapeType::Cylinder, 0.06f, 0.06f, 0.065f), kUp));
}

// A standing mug fitted by a cylinder on its side (the RealSense mug at 1.16 m: r 49 mm, 75 mm
// long, through its handle) is the wrong solid, though a cylinder.
TEST(EverydayScoring, StandingCylinderMustStand) {
  const GroundTruthObject mug = uprightTruth(ShapeType::Cylinder, 0.041f, 0.041f, 0.095f);
  EXPECT_TRUE(expectedSolid(mug, fittedSolid(ShapeType::Cylinder, 0.042f, 0.042f, 0.097f), kUp));
  const ShapeFit lying = fittedSolid(ShapeType::Cylinder, 0.0493f, 0.0493f, 0.075f, kAxisAlongX);
  EXPECT_FALSE(expectedSolid(mug, lying, kUp));
  EXPECT_NEAR(oversizePercent(mug, lying, kUp), 100.0 * (0.0986 / 0.082 - 1), 0.01);
}

// A lying can: a lying cylinder or its bounding box is right, an upright cylinder is not.
TEST(EverydayScoring, LyingCanIsALyingCylinderOrItsBox) {
  GroundTruthObject can = uprightTruth(ShapeType::Cylinder, 0.033f, 0.033f, 0.101f);
  can.form = ObjectForm::LyingCan;
  can.orientation = kAxisAlongX;
  EXPECT_TRUE(solidExtents(can, kUp).isApprox(Eigen::Vector3f(0.101f, 0.066f, 0.066f)));

  const ShapeFit lying = fittedSolid(ShapeType::Cylinder, 0.033f, 0.033f, 0.101f, kAxisAlongX);
  EXPECT_TRUE(expectedSolid(can, lying, kUp));
  EXPECT_NEAR(oversizePercent(can, lying, kUp), 0.0, 1e-4);
  for (const Measure& m : dimensionErrors(can, lying, kUp)) EXPECT_NEAR(m.error_percent, 0, 1e-4);

  ShapeFit box = fittedSolid(ShapeType::Cube, 0, 0, 0);
  box.dimensions = {0.066f, 0.101f, 0.066f};
  EXPECT_TRUE(expectedSolid(can, box, kUp));
  const std::vector<Measure> box_errors = dimensionErrors(can, box, kUp);
  ASSERT_EQ(box_errors.size(), 3u);  // length, width, height of the can's bounding box
  for (const Measure& m : box_errors) EXPECT_NEAR(m.error_percent, 0, 1e-4) << m.name;

  const ShapeFit upright = fittedSolid(ShapeType::Cylinder, 0.0505f, 0.0505f, 0.066f);
  EXPECT_FALSE(expectedSolid(can, upright, kUp));
  EXPECT_NEAR(oversizePercent(can, upright, kUp), 100.0 * (0.101 / 0.066 - 1), 0.01);
}

// A rendered scene labelled as OSD labels its files (table 1, object i 10 * (i + 2)), and a box
// fit (cube) centred `height` above the table at the object's footprint centre.
pcl::PointCloud<pcl::PointXYZRGBL> osdLabelled(const RenderedScene& scene) {
  pcl::PointCloud<pcl::PointXYZRGBL> cloud(scene.cloud->width, scene.cloud->height);
  for (size_t i = 0; i < scene.cloud->size(); ++i) {
    cloud[i].getVector3fMap() = (*scene.cloud)[i].getVector3fMap();
    const int label = scene.labels[i];
    cloud[i].label = label >= 0 ? 10 * (label + 2) : label == kTableLabel ? 1 : 0;
  }
  return cloud;
}
ShapeFit boxCentredAt(const RenderedScene& scene, const ObjectSpec& object, float height) {
  ShapeFit fit = fittedSolid(ShapeType::Cube, 0, 0, 0);
  const Eigen::Vector3f world(object.position_on_table.x(), object.position_on_table.y(),
                              scene.spec.table.height + height);
  fit.center = scene.world_from_camera.inverse() * world;
  return fit;
}

// A 25 cm box 10 cm behind a 20 cm one, its lower 17 cm hidden: a fit standing on the table
// (centre 12.5 cm up, 4.5 cm under its visible points) finds it (OSD learn16). A box resting on a
// lower one shows the lower one's top below it: a fit reaching down to the table stays junk.
TEST(LabelledScoring, ObjectWhoseBottomAnotherHidesReachesDownToTheTable) {
  SceneSpec spec;
  spec.noise = NoiseModel::noiseless();
  spec.placement = {0.8f, 30.0f, 0.0f};
  ObjectSpec front, behind;
  front.box_size = {0.1f, 0.1f, 0.2f};
  front.position_on_table = {-0.1f, 0.0f};
  behind.box_size = {0.1f, 0.1f, 0.25f};
  behind.position_on_table = {0.1f, 0.0f};
  spec.objects = {front, behind};
  RenderedScene scene = renderScene(spec);
  const auto boxes = [](int) { return ExpectedShape::Box; };
  LabelledObjectScore score = scoreLabelledObjects(
      osdLabelled(scene), {boxCentredAt(scene, front, 0.1f), boxCentredAt(scene, behind, 0.125f)},
      boxes);
  EXPECT_EQ(score.whole.objects, 2);
  EXPECT_EQ(score.whole.found, 2);
  EXPECT_EQ(score.whole.junk, 0);
  EXPECT_EQ(score.parts.found, 2);

  ObjectSpec lower, upper;
  lower.box_size = {0.2f, 0.2f, 0.15f};
  upper.box_size = {0.1f, 0.1f, 0.06f};
  upper.base_height = 0.15f;
  upper.position_on_table = {0.03f, 0.0f};
  spec.objects = {lower, upper};
  scene = renderScene(spec);
  const pcl::PointCloud<pcl::PointXYZRGBL> stack = osdLabelled(scene);
  score = scoreLabelledObjects(
      stack, {boxCentredAt(scene, lower, 0.075f), boxCentredAt(scene, upper, 0.18f)}, boxes);
  EXPECT_EQ(score.whole.found, 2);
  // The upper box fitted down to the table (21 cm tall, centre 10.5 cm up) does not find it.
  score = scoreLabelledObjects(
      stack, {boxCentredAt(scene, lower, 0.075f), boxCentredAt(scene, upper, 0.105f)}, boxes);
  EXPECT_EQ(score.whole.found, 1);
  EXPECT_EQ(score.whole.pieces + score.whole.junk, 1);
}

TEST(SceneRenderer, DegenerateInputDoesNotCrash) {
  SceneSpec spec;
  spec.camera.width = 0;
  EXPECT_EQ(renderScene(spec).cloud->size(), 0u);
  spec = SceneSpec();
  ObjectSpec flat = steelMug();
  flat.height = 0.0f;  // skipped
  ObjectSpec empty_box = teapotBox();
  empty_box.box_size.setZero();
  spec.objects = {flat, empty_box};
  const RenderedScene scene = renderScene(spec);
  EXPECT_EQ(scene.objects.size(), 2u);
  EXPECT_EQ(scene.objects[0].visible_pixels, 0);
  EXPECT_EQ(scene.objects[1].visible_pixels, 0);
  RandomSceneOptions impossible;
  impossible.min_objects = impossible.max_objects = 4;
  impossible.table.length = impossible.table.width = 0.3f;  // nothing fits inside the margin
  std::mt19937 rng(1);
  EXPECT_LE(randomScene(rng, impossible).objects.size(), 4u);
}

}  // namespace
}  // namespace sim
}  // namespace tabletop_shapes
