// §2.1 preprocessing: known-answer tests of the range filter and the centroid voxel grid.
#include "tabletop_shapes/core/preprocess.h"

#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/voxel_key.h"

#include <gtest/gtest.h>
#include <pcl/common/io.h>

#include <cmath>
#include <limits>
#include <map>
#include <tuple>
#include <vector>

namespace tabletop_shapes {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

using VoxelKey = std::tuple<int64_t, int64_t, int64_t>;

// Reference voxel grid: a std::map from voxel to the double sum of its valid points in range.
std::map<VoxelKey, Eigen::Vector4d> referenceVoxels(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                                                    float leaf, float max_range) {
  std::map<VoxelKey, Eigen::Vector4d> voxels;
  const float inv_leaf = 1.0f / leaf;  // the same rounding at voxel borders as the filter
  for (const auto& p : cloud) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    if (p.getVector3fMap().norm() > max_range) continue;
    const VoxelKey key{static_cast<int64_t>(std::floor(p.x * inv_leaf)),
                       static_cast<int64_t>(std::floor(p.y * inv_leaf)),
                       static_cast<int64_t>(std::floor(p.z * inv_leaf))};
    auto it = voxels.emplace(key, Eigen::Vector4d::Zero()).first;
    it->second += Eigen::Vector4d(p.x, p.y, p.z, 1.0);
  }
  return voxels;
}

// An organised VGA cloud of a slanted wall 1-2 m away with NaN holes (every 7th pixel and a
// whole band of rows) and a few infinities, as a depth camera delivers it.
pcl::PointCloud<pcl::PointXYZ> vgaCloud() {
  pcl::PointCloud<pcl::PointXYZ> cloud(640, 480);
  cloud.is_dense = false;
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      const float x = (u - 320) / 525.0f, y = (v - 240) / 525.0f;
      const float depth = 1.0f + 0.5f * (u / 640.0f) + 0.0003f * ((u * 7 + v * 13) % 10);
      pcl::PointXYZ& p = cloud.at(u, v);
      p = pcl::PointXYZ(x * depth, y * depth, depth);
      if ((u + 640 * v) % 7 == 0 || (v >= 100 && v < 120)) p = pcl::PointXYZ(kNaN, kNaN, kNaN);
      if (u == 5 && v % 50 == 0) p.z = kInf;
    }
  }
  return cloud;
}

TEST(Preprocess, CentroidsOnHandMadeGrid) {
  // Leaf 0.1 m: two points in voxel (0,0,0), one in (1,0,0), two in (-1,-1,-1).
  pcl::PointCloud<pcl::PointXYZ> in;
  in.push_back({0.01f, 0.02f, 0.03f});
  in.push_back({0.15f, 0.05f, 0.05f});  // voxel (1,0,0)
  in.push_back({0.05f, 0.06f, 0.07f});
  in.push_back({-0.02f, -0.03f, -0.04f});
  in.push_back({-0.08f, -0.05f, -0.06f});
  in.push_back({kNaN, 0.0f, 0.0f});  // skipped
  in.header.frame_id = "camera";
  in.header.stamp = 42;
  Preprocessor pre(PreprocessParams{0.1f, 3.0f});
  Cloud out;
  pre.apply(in, out);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out.height, 1u);
  EXPECT_EQ(out.width, 3u);
  EXPECT_TRUE(out.is_dense);
  EXPECT_EQ(out.header.frame_id, "camera");
  EXPECT_EQ(out.header.stamp, 42u);
  // Voxels come out in the order they are first met.
  EXPECT_NEAR(out[0].x, 0.03f, 1e-6f);
  EXPECT_NEAR(out[0].y, 0.04f, 1e-6f);
  EXPECT_NEAR(out[0].z, 0.05f, 1e-6f);
  EXPECT_NEAR(out[1].x, 0.15f, 1e-6f);
  EXPECT_NEAR(out[1].y, 0.05f, 1e-6f);
  EXPECT_NEAR(out[1].z, 0.05f, 1e-6f);
  EXPECT_NEAR(out[2].x, -0.05f, 1e-6f);
  EXPECT_NEAR(out[2].y, -0.04f, 1e-6f);
  EXPECT_NEAR(out[2].z, -0.05f, 1e-6f);
}

TEST(Preprocess, RangeFilterWithoutGrid) {
  pcl::PointCloud<pcl::PointXYZ> in;
  in.push_back({0.0f, 0.0f, 1.0f});
  in.push_back({0.0f, 2.9f, 0.0f});
  in.push_back({1.8f, 0.0f, 2.39f});               // |p| just below 3.0: kept
  in.push_back({0.0f, 0.0f, 3.1f});                // too far
  in.push_back({3.0f, 3.0f, 3.0f});                // too far
  in.push_back({kInf, 0.0f, 1.0f});                // invalid
  Preprocessor pre(PreprocessParams{0.0f, 3.0f});  // leaf 0: no voxel grid
  Cloud out;
  pre.apply(in, out);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_FLOAT_EQ(out[0].z, 1.0f);
  EXPECT_FLOAT_EQ(out[1].y, 2.9f);
  EXPECT_FLOAT_EQ(out[2].x, 1.8f);
  // With the grid on, a far point still never reaches the output.
  pre.setParams(PreprocessParams{0.05f, 3.0f});
  pre.apply(in, out);
  EXPECT_EQ(out.size(), 3u);
  for (const auto& p : out) EXPECT_LE(p.getVector3fMap().norm(), 3.0f + 1e-5f);
}

TEST(Preprocess, OrganisedVgaMatchesReferenceGrid) {
  const pcl::PointCloud<pcl::PointXYZ> in = vgaCloud();
  const PreprocessParams params{0.005f, 1.4f};  // the range cuts part of the wall
  const auto reference = referenceVoxels(in, params.leaf_size, params.max_range);
  Preprocessor pre(params);
  Cloud out;
  for (int run = 0; run < 2; ++run) {  // the second run reuses the buffers
    pre.apply(in, out);
    ASSERT_EQ(out.size(), reference.size());
    EXPECT_EQ(out.height, 1u);
    EXPECT_TRUE(out.is_dense);
    size_t matched = 0;
    for (const auto& p : out) {
      ASSERT_TRUE(p.getVector3fMap().allFinite());
      const float inv_leaf = 1.0f / params.leaf_size;
      const VoxelKey key{static_cast<int64_t>(std::floor(p.x * inv_leaf)),
                         static_cast<int64_t>(std::floor(p.y * inv_leaf)),
                         static_cast<int64_t>(std::floor(p.z * inv_leaf))};
      const auto it = reference.find(key);
      ASSERT_NE(it, reference.end());
      const Eigen::Vector3d centroid = it->second.head<3>() / it->second.w();
      EXPECT_NEAR((p.getVector3fMap().cast<double>() - centroid).norm(), 0.0, 1e-6);
      ++matched;
    }
    EXPECT_EQ(matched, reference.size());
  }
}

// The pixels are judged on bands of rows on all worker threads: the cloud is the same, point for
// point and in order, whatever their number.
TEST(Preprocess, SameCloudWithOneTwoAndFiveThreads) {
  const pcl::PointCloud<pcl::PointXYZ> in = vgaCloud();
  Cloud reference, out;
  setWorkerThreads(1);
  Preprocessor().apply(in, reference);
  ASSERT_GT(reference.size(), 10000u);
  for (const unsigned threads : {2u, 5u}) {
    setWorkerThreads(threads);
    Preprocessor().apply(in, out);
    ASSERT_EQ(out.size(), reference.size()) << threads << " threads";
    for (size_t i = 0; i < out.size(); ++i) {
      ASSERT_EQ(out[i].getVector3fMap(), reference[i].getVector3fMap()) << i;
    }
  }
  setWorkerThreads(0);
}

// A voxel whose points lie in two bands of rows (keyed on different threads) gets them added in
// image order, as one pass over the image adds them: here the order decides the float centroid
// (summing per band and adding the bands' sums would give 0.25 + 2^-25). Voxel (0, 0, 0) of a 2 m
// grid holds x = 1, 2^-24 (row 0's band) and twice 3 * 2^-55 (row 1's band). In image order
// the double sum stays at 1 + 2^-24 (each 3 * 2^-55 is below half its last bit), whose quarter
// 0.25 + 2^-26 lies halfway between two floats and rounds to the even 0.25; the band's own sum
// 2^-24 + 6 * 2^-55 added at once would round up to 1 + 2^-24 + 2^-52, hence 0.25 + 2^-25.
TEST(Preprocess, VoxelSumsAddInImageOrderWhateverTheBands) {
  pcl::PointCloud<pcl::PointXYZ> in(3, 8, pcl::PointXYZ(kNaN, kNaN, kNaN));
  const float tiny = std::ldexp(3.0f, -55);
  in.at(0, 0) = pcl::PointXYZ(1.0f, 0.5f, 1.0f);
  in.at(0, 1) = pcl::PointXYZ(std::ldexp(1.0f, -24), 0.5f, 1.0f);
  in.at(1, 1) = pcl::PointXYZ(tiny, 0.5f, 1.0f);
  in.at(2, 1) = pcl::PointXYZ(tiny, 0.5f, 1.0f);
  const PreprocessParams params{2.0f, 3.0f, 0.0f};  // no flying pixel test: lone points
  for (const unsigned threads : {1u, 2u, 5u}) {     // 1, 8 and 8 bands of one row
    setWorkerThreads(threads);
    Cloud out;
    Preprocessor(params).apply(in, out);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_EQ(out[0].x, 0.25f) << threads << " threads";
    EXPECT_EQ(out[0].y, 0.5f);
    EXPECT_EQ(out[0].z, 1.0f);
  }
  setWorkerThreads(0);
}

// The voxel sums are shared out between threads by the sides of the camera frame (the sign of
// x); each thread skips the other's side. Whichever thread sums a voxel, the voxels come out in
// the order their first points are met in the image, each the centroid of its points added in
// image order, as one pass over the image gives them. The rows' first 64 pixels run slowly along
// x across x = 0 (four pixels per voxel: long runs of one side to skip), the others jump across
// x = 0 from pixel to pixel; NaN holes in both.
TEST(Preprocess, VoxelsComeOutInTheOrderFirstMetWhicheverThreadSumsThem) {
  const int width = 101, height = 7;
  pcl::PointCloud<pcl::PointXYZ> in(width, height);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const float x =
          u < 64 ? 0.0025f * u + 0.0003f * v - 0.08f : 0.01f * ((u * 7 + v * 3) % 40) - 0.197f;
      in.at(u, v) = (u + v) % 9 == 0
                        ? pcl::PointXYZ(kNaN, kNaN, kNaN)
                        : pcl::PointXYZ(x, 0.01f * (v / 2) + 0.0001f * u - 0.015f, 1.0f);
    }
  }
  const float leaf = 0.01f, inv_leaf = 1.0f / leaf;  // the filter's rounding at voxel borders
  // Reference: voxels numbered as first met in image order, sums in image order.
  std::map<VoxelKey, size_t> index;
  std::vector<Eigen::Vector4d> sums;
  for (const auto& p : in) {
    if (!std::isfinite(p.x)) continue;
    const VoxelKey key{static_cast<int64_t>(std::floor(p.x * inv_leaf)),
                       static_cast<int64_t>(std::floor(p.y * inv_leaf)),
                       static_cast<int64_t>(std::floor(p.z * inv_leaf))};
    const auto it = index.emplace(key, sums.size()).first;
    if (it->second == sums.size()) sums.emplace_back(Eigen::Vector4d::Zero());
    sums[it->second] += Eigen::Vector4d(p.x, p.y, p.z, 1.0);
  }
  ASSERT_GT(sums.size(), 100u);
  for (const unsigned threads : {1u, 2u, 3u, 5u}) {
    setWorkerThreads(threads);
    Cloud out;
    Preprocessor(PreprocessParams{leaf, 3.0f, 0.0f}).apply(in, out);
    ASSERT_EQ(out.size(), sums.size()) << threads << " threads";
    for (size_t i = 0; i < sums.size(); ++i) {
      const double inv_count = 1.0 / sums[i].w();
      ASSERT_EQ(out[i].x, static_cast<float>(sums[i].x() * inv_count)) << i << ", " << threads;
      ASSERT_EQ(out[i].y, static_cast<float>(sums[i].y() * inv_count)) << i << ", " << threads;
      ASSERT_EQ(out[i].z, static_cast<float>(sums[i].z() * inv_count)) << i << ", " << threads;
    }
  }
  setWorkerThreads(0);
}

// The view bounds come from the preprocessing's own pass over the pixels: the same as
// viewBoundsOf's, whatever the number of threads, and near the known camera's (focal 525 px,
// principal point (320, 240), the wall's columns 0-639 and rows 0-479 valid somewhere).
TEST(Preprocess, ViewBoundsFromTheSamePassAreViewBoundsOfs) {
  const pcl::PointCloud<pcl::PointXYZ> in = vgaCloud();
  const ViewBounds reference = viewBoundsOf(in);
  ASSERT_TRUE(reference.known);
  EXPECT_NEAR(reference.min_tan_x, -320.0f / 525.0f, 1e-6f);
  EXPECT_NEAR(reference.max_tan_x, 319.0f / 525.0f, 1e-6f);
  EXPECT_NEAR(reference.min_tan_y, -240.0f / 525.0f, 1e-6f);
  EXPECT_NEAR(reference.max_tan_y, 239.0f / 525.0f, 1e-6f);
  EXPECT_NEAR(reference.pixel_tan, 1.0f / 525.0f, 1e-7f);
  EXPECT_NEAR(reference.min_depth, 1.0f, 1e-6f);
  for (const unsigned threads : {1u, 2u, 5u}) {
    setWorkerThreads(threads);
    Cloud out;
    ViewBounds view;
    Preprocessor().apply(in, out, &view);
    EXPECT_TRUE(view.known);
    EXPECT_EQ(view.min_tan_x, reference.min_tan_x) << threads << " threads";
    EXPECT_EQ(view.max_tan_x, reference.max_tan_x);
    EXPECT_EQ(view.min_tan_y, reference.min_tan_y);
    EXPECT_EQ(view.max_tan_y, reference.max_tan_y);
    EXPECT_EQ(view.pixel_tan, reference.pixel_tan);
    EXPECT_EQ(view.min_depth, reference.min_depth);
  }
  setWorkerThreads(0);
  // 637 columns: pixels four at a time, then the last one alone.
  pcl::PointCloud<pcl::PointXYZ> narrow(637, 480);
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 637; ++u) narrow.at(u, v) = in.at(u + 3, v);
  }
  ViewBounds narrow_view;
  Cloud narrow_out;
  Preprocessor().apply(narrow, narrow_out, &narrow_view);
  const ViewBounds narrow_reference = viewBoundsOf(narrow);
  EXPECT_EQ(narrow_view.min_tan_x, narrow_reference.min_tan_x);
  EXPECT_EQ(narrow_view.max_tan_x, narrow_reference.max_tan_x);
  EXPECT_EQ(narrow_view.pixel_tan, narrow_reference.pixel_tan);
  EXPECT_NEAR(narrow_view.max_tan_x, 319.0f / 525.0f, 1e-6f);
  // An unorganised cloud has no image: unknown, as viewBoundsOf says.
  pcl::PointCloud<pcl::PointXYZ> unorganised = in;
  unorganised.width = static_cast<uint32_t>(in.size());
  unorganised.height = 1;
  Cloud out;
  ViewBounds view;
  view.known = true;
  Preprocessor().apply(unorganised, out, &view);
  EXPECT_FALSE(view.known);
  EXPECT_FALSE(viewBoundsOf(unorganised).known);
}

TEST(Preprocess, ColourInputGivesTheSameCloudAndInPlaceWorks) {
  const pcl::PointCloud<pcl::PointXYZ> xyz = vgaCloud();
  pcl::PointCloud<pcl::PointXYZRGBA> rgba;
  pcl::copyPointCloud(xyz, rgba);
  Preprocessor pre;
  Cloud from_xyz, from_rgba;
  pre.apply(xyz, from_xyz);
  pre.apply(rgba, from_rgba);
  ASSERT_EQ(from_xyz.size(), from_rgba.size());
  ASSERT_GT(from_xyz.size(), 10000u);
  for (size_t i = 0; i < from_xyz.size(); ++i) {
    ASSERT_EQ(from_xyz[i].getVector3fMap(), from_rgba[i].getVector3fMap());
  }
  Cloud in_place = xyz;
  pre.apply(in_place, in_place);
  ASSERT_EQ(in_place.size(), from_xyz.size());
  EXPECT_EQ(in_place[0].getVector3fMap(), from_xyz[0].getVector3fMap());
}

TEST(Preprocess, EmptyAndAllNaNGiveEmptyOutput) {
  Preprocessor pre;
  Cloud out;
  out.push_back({1.0f, 2.0f, 3.0f});  // stale content must go
  pre.apply(pcl::PointCloud<pcl::PointXYZ>(), out);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(out.width, 0u);
  pcl::PointCloud<pcl::PointXYZ> nans(640, 480, pcl::PointXYZ(kNaN, kNaN, kNaN));
  pre.apply(nans, out);
  EXPECT_TRUE(out.empty());
  pre.setParams(PreprocessParams{0.0f, 3.0f});
  pre.apply(nans, out);
  EXPECT_TRUE(out.empty());
}

// Depth image of a fronto-parallel box face (z = 1 m, columns 40-79) before a floor seen at a
// 15 deg grazing angle (its depth grows ~1 cm per row), with flying pixels: every other row,
// the pixel on either side of the box's left edge lies between the two depths.
TEST(Preprocess, FlyingPixelsAtDepthEdgesAreDropped) {
  const float focal = 575.0f;
  pcl::PointCloud<pcl::PointXYZ> in(120, 80);
  const Eigen::Vector3f floor_normal(0.0f, -std::cos(degToRad(15.0f)), -std::sin(degToRad(15.0f)));
  const Eigen::Vector3f floor_point(0.0f, 0.0f, 2.0f);
  auto depthOfPixel = [&](int u, int v) {
    const Eigen::Vector3f ray((u - 60) / focal, (v - 40) / focal, 1.0f);
    if (u >= 40 && u < 80) return 1.0f;
    return floor_normal.dot(floor_point) / floor_normal.dot(ray);  // ray-plane, as z
  };
  size_t flying = 0;
  for (int v = 0; v < 80; ++v) {
    for (int u = 0; u < 120; ++u) {
      float z = depthOfPixel(u, v);
      const bool edge = u == 39 || u == 40;
      if (edge && v % 2 == 0) {  // 30 % / 70 % of the way between box and floor
        z = 1.0f + (u == 39 ? 0.3f : 0.7f) * (depthOfPixel(38, v) - 1.0f);
        ++flying;
      }
      in.at(u, v) = pcl::PointXYZ((u - 60) / focal * z, (v - 40) / focal * z, z);
    }
  }
  PreprocessParams params{0.0f, 10.0f};  // no voxel grid: every kept point comes out
  Cloud out;
  Preprocessor(params).apply(in, out);
  EXPECT_EQ(out.size(), in.size() - flying);
  for (const auto& p : out) {
    const int u = static_cast<int>(std::lround(p.x / p.z * focal + 60));
    const int v = static_cast<int>(std::lround(p.y / p.z * focal + 40));
    EXPECT_NEAR(p.z, depthOfPixel(u, v), 1e-4f) << "flying pixel kept at " << u << ", " << v;
  }
  // The same cloud in a frame whose origin is not the camera: lines of sight start at the
  // cloud's sensor origin, so the same points are dropped.
  pcl::PointCloud<pcl::PointXYZ> moved = in;
  const Eigen::Vector3f offset(0.4f, -1.1f, 0.7f);
  for (auto& p : moved) p.getVector3fMap() += offset;
  moved.sensor_origin_.head<3>() = offset;
  Preprocessor(params).apply(moved, out);
  EXPECT_EQ(out.size(), in.size() - flying);
  params.flying_pixel_angle_deg = 0.0f;  // off: all points stay
  Preprocessor(params).apply(in, out);
  EXPECT_EQ(out.size(), in.size());
}

// The flying pixel test point for point against its definition (kept when a finite image
// neighbour lies off its line of sight by more than the angle, or when it has no finite
// neighbour), with the float operations in the filter's order: stripes three pixels wide at two
// depths (a stripe's first pixel is cleared by its right neighbour, not its left), lone pixels
// between the depths, holes, and rows of 45 pixels (not four at a time to the end).
TEST(Preprocess, FlyingPixelsAreTheDefinitionsPixelForPixel) {
  const int width = 45, height = 12;
  pcl::PointCloud<pcl::PointXYZ> in(width, height);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      float z = 1.0f + 0.4f * static_cast<float>((u / 3 + v) % 2);
      if ((u + 5 * v) % 11 == 0) z = 1.17f;  // between the depths
      pcl::PointXYZ& p = in.at(u, v);
      p = pcl::PointXYZ((u - 22) / 500.0f * z, (v - 6) / 500.0f * z, z);
      if ((7 * u + 3 * v) % 13 == 0) p.z = kNaN;
    }
  }
  in.sensor_origin_.head<3>() = Eigen::Vector3f(0.01f, -0.02f, 0.005f);
  const PreprocessParams params{0.0f, 10.0f, 10.0f};  // no voxel grid: every kept point comes out
  const float cot = 1.0f / std::tan(degToRad(params.flying_pixel_angle_deg));
  const float cot_sq = cot * cot, along_weight = 1.0f + cot_sq;
  const Eigen::Vector3f eye = in.sensor_origin_.head<3>();
  std::vector<pcl::PointXYZ> kept;
  size_t dropped = 0, kept_across_left_edge = 0;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const pcl::PointXYZ& p = in.at(u, v);
      if (!std::isfinite(p.z)) continue;
      const float sx = p.x - eye.x(), sy = p.y - eye.y(), sz = p.z - eye.z();
      const float sight_sq = sx * sx + sy * sy + sz * sz;
      auto onSurface = [&](const pcl::PointXYZ& q) {
        const float dx = q.x - p.x, dy = q.y - p.y, dz = q.z - p.z;
        const float dot = dx * sx + dy * sy + dz * sz;
        return dot * dot * along_weight <= cot_sq * (dx * dx + dy * dy + dz * dz) * sight_sq;
      };
      bool any_neighbour = false, surface = false;
      for (int dv = -1; dv <= 1; ++dv) {
        for (int du = -1; du <= 1; ++du) {
          const int nu = u + du, nv = v + dv;
          if ((du == 0 && dv == 0) || nu < 0 || nu >= width || nv < 0 || nv >= height) continue;
          const pcl::PointXYZ& q = in.at(nu, nv);
          if (!std::isfinite(q.z)) continue;
          any_neighbour = true;
          surface = surface || onSurface(q);
        }
      }
      if (any_neighbour && !surface) {
        ++dropped;
        continue;
      }
      kept.push_back(p);
      const bool left = u > 0 && std::isfinite(in.at(u - 1, v).z);
      if (left && !onSurface(in.at(u - 1, v))) ++kept_across_left_edge;
    }
  }
  EXPECT_GT(dropped, 20u);
  EXPECT_GT(kept_across_left_edge, 50u);
  Cloud out;
  Preprocessor(params).apply(in, out);
  ASSERT_EQ(out.size(), kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    EXPECT_EQ(out[i].x, kept[i].x) << "point " << i;
    EXPECT_EQ(out[i].y, kept[i].y) << "point " << i;
    EXPECT_EQ(out[i].z, kept[i].z) << "point " << i;
  }
}

// Issue 16, finding 5: one 5-million-point frame kept the manager at 490-600 MB for good. The
// buffers a burst left behind are given back on the next normal frame; results stay exact.
TEST(Preprocess, BuffersShrinkAfterAFrameFarAboveTheUsualSize) {
  Preprocessor preprocessor;
  Cloud out, reference;
  const pcl::PointCloud<pcl::PointXYZ> normal = vgaCloud();
  preprocessor.apply(normal, reference);
  const size_t normal_bytes = preprocessor.bufferBytes();
  pcl::PointCloud<pcl::PointXYZ> burst;  // 1.5 million points, nearly one voxel each
  for (int i = 0; i < 1500000; ++i) {
    burst.push_back({0.006f * (i % 400), 0.006f * ((i / 400) % 400), 0.5f + 0.006f * (i / 160000)});
  }
  preprocessor.apply(burst, out);
  EXPECT_GT(out.size(), 1000000u);
  EXPECT_GT(preprocessor.bufferBytes(), 10 * normal_bytes);
  preprocessor.apply(normal, out);
  EXPECT_LE(preprocessor.bufferBytes(), normal_bytes) << "normal frame: " << normal_bytes;
  ASSERT_EQ(out.size(), reference.size());
  for (size_t i = 0; i < out.size(); ++i) {
    ASSERT_EQ(out.points[i].getVector3fMap(), reference.points[i].getVector3fMap()) << i;
  }
  preprocessor.apply(normal, out);  // grows again from the small start, same answer
  ASSERT_EQ(out.size(), reference.size());
}

}  // namespace
}  // namespace tabletop_shapes

#ifdef __SSE2__
// The four-pixel keying writes pack()'s keys, and kEmpty for the pixels not kept: negative
// coordinates, both ends of the packable range, every mask of kept lanes.
TEST(Preprocess, PackFourGivesPackOfTheKeptLanes) {
  namespace vk = tabletop_shapes::voxel_key;
  const int32_t far = static_cast<int32_t>(vk::kAxisOffset - 1);
  const int32_t xs[4] = {0, -1, far, -far}, ys[4] = {-far, 7, -300, far},
                zs[4] = {far, -far, 0, 12};
  for (int kept_lanes = 0; kept_lanes < 16; ++kept_lanes) {
    uint64_t keys[4];
    vk::packFour(_mm_setr_epi32(xs[0], xs[1], xs[2], xs[3]),
                 _mm_setr_epi32(ys[0], ys[1], ys[2], ys[3]),
                 _mm_setr_epi32(zs[0], zs[1], zs[2], zs[3]), kept_lanes, keys);
    for (int lane = 0; lane < 4; ++lane) {
      const uint64_t expected =
          kept_lanes >> lane & 1 ? vk::pack(xs[lane], ys[lane], zs[lane]) : vk::kEmpty;
      EXPECT_EQ(keys[lane], expected) << "lanes kept " << kept_lanes << ", lane " << lane;
    }
  }
}
#endif
