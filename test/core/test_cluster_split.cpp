// Concave-seam split (beyond the paper): known answers on synthetic objects seen from one camera.
// Stacked objects come apart; single boxes, cylinders, cones and a cup with its inside do not.
#include "tabletop_shapes/core/cluster_split.h"

#include "tabletop_shapes/core/clustering.h"
#include "tabletop_shapes/core/object_fitting.h"
#include "synthetic.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace tabletop_shapes {
namespace {

// A Kinect v1 depth image's steps: the disparity (focal length x baseline / depth) comes in
// 1/8 pixel steps, so depths come in steps of 2.9 mm x (depth / 1 m)^2. Camera frame.
void toDisparitySteps(Cloud& cloud) {
  const float focal_baseline = 575.8f * 0.075f;  // [px m]
  for (auto& p : cloud.points) {
    const float disparity = std::round(focal_baseline / p.z * 8.0f) / 8.0f;
    p.getVector3fMap() *= focal_baseline / disparity / p.z;
  }
}

struct SeenCluster {
  CloudPtr cluster;
  Plane table;
};

// Moves the table frame into a camera frame (camera at the origin, as the core assumes) and
// returns the scene as the one Euclidean cluster the pipeline hands over.
SeenCluster seenCluster(Cloud scene, const synthetic::Sampler& s = synthetic::voxelGridSampler(),
                        bool disparity_steps = false) {
  const Eigen::Isometry3f camera_from_table = synthetic::cameraFromTable(s);
  synthetic::transformCloud(camera_from_table, scene);
  if (disparity_steps) toDisparitySteps(scene);
  const Plane table = synthetic::transformPlane(camera_from_table, synthetic::tablePlane());
  auto cloud = std::make_shared<Cloud>(scene);
  cloud->width = static_cast<uint32_t>(cloud->size());
  cloud->height = 1;
  const std::vector<CloudPtr> clusters = extractClusters(cloud, ClusteringParams());
  EXPECT_EQ(clusters.size(), 1u);
  return {clusters.at(0), table};
}

std::vector<CloudPtr> split(Cloud scene,
                            const synthetic::Sampler& s = synthetic::voxelGridSampler(),
                            bool disparity_steps = false) {
  const SeenCluster seen = seenCluster(std::move(scene), s, disparity_steps);
  return splitAtConcaveSeams(seen.cluster, seen.table, ClusteringParams());
}

bool mayHoldAStack(Cloud scene) {
  const SeenCluster seen = seenCluster(std::move(scene));
  return mayHoldAStack(*seen.cluster, seen.table, ClusteringParams());
}

// As many parts as objects, each the size of one of them (within `tolerance`); sizes add up.
void expectPartsMatch(const std::vector<CloudPtr>& parts, const std::vector<CloudPtr>& objects,
                      float tolerance = 0.1f) {
  ASSERT_EQ(parts.size(), objects.size());
  size_t total = 0, objects_total = 0;
  for (const auto& p : parts) total += p->size();
  for (const auto& o : objects) objects_total += o->size();
  EXPECT_NEAR(total, objects_total, 0.01 * objects_total);  // a few stray points may drop
  for (const auto& part : parts) {
    bool matched = false;
    for (const auto& object : objects) {
      matched |=
          std::abs(static_cast<float>(part->size()) - object->size()) < tolerance * object->size();
    }
    EXPECT_TRUE(matched) << "part of " << part->size() << " points; objects of " << [&] {
      std::string sizes;
      for (const auto& o : objects) sizes += std::to_string(o->size()) + " ";
      return sizes;
    }();
  }
}

// A box 16 x 10 x 5 cm lying on a box 24 x 16 x 6 cm, and the lower box's visible points.
struct BoxOnBox {
  CloudPtr lower_visible, upper;
  Cloud scene;
};
BoxOnBox boxOnBox() {
  BoxOnBox stack;
  const CloudPtr lower =
      synthetic::box({0.24f, 0.16f, 0.06f}, {0.0f, 0.0f}, 0.0f, synthetic::voxelGridSampler());
  stack.upper = synthetic::lifted(
      synthetic::box({0.16f, 0.10f, 0.05f}, {0.01f, 0.01f}, 0.3f, synthetic::voxelGridSampler()),
      0.06f);
  stack.lower_visible = synthetic::withoutFootprint(lower, -0.08f, 0.1f, -0.06f, 0.08f, 0.06f);
  stack.scene = *stack.lower_visible;
  stack.scene += *stack.upper;
  return stack;
}

TEST(ClusterSplit, BoxStackedOnABox) {
  const BoxOnBox stack = boxOnBox();
  const CloudPtr &lower_visible = stack.lower_visible, &upper = stack.upper;
  const Cloud& scene = stack.scene;
  // Within 3 %: the strips of the lower box's top face around the upper box touch the upper
  // box most, but meet it at the concave seam, and belong to the lower box (they went to the
  // upper one, 9 % off, when small parts simply joined the part they touched most).
  expectPartsMatch(split(scene), {lower_visible, upper}, 0.03f);
}

TEST(ClusterSplit, CylinderStandingOnARoundTin) {
  const CloudPtr tin =
      synthetic::roundObject(0.10f, 0.10f, 0.05f, {0.0f, 0.0f}, synthetic::voxelGridSampler());
  const CloudPtr can = synthetic::lifted(
      synthetic::roundObject(0.035f, 0.035f, 0.09f, {0.0f, 0.0f}, synthetic::voxelGridSampler()),
      0.05f);
  auto tin_visible = std::make_shared<Cloud>();
  for (const auto& p : *tin) {
    if (std::hypot(p.x, p.y) > 0.036f || p.z < 0.049f) tin_visible->push_back(p);
  }
  Cloud scene = *tin_visible;
  scene += *can;
  expectPartsMatch(split(scene), {tin_visible, can});
}

// The cheap test before the split: a stack has points below its top band and beside it; a single
// box, cylinder, cup or cone opening up has every point under its top's footprint.
TEST(ClusterSplit, OnlyClustersThatCanHoldAStackAreSplit) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  EXPECT_TRUE(mayHoldAStack(boxOnBox().scene));
  Cloud can_on_tin = *synthetic::roundObject(0.10f, 0.10f, 0.05f, {0.0f, 0.0f}, s);
  can_on_tin +=
      *synthetic::lifted(synthetic::roundObject(0.035f, 0.035f, 0.09f, {0.0f, 0.0f}, s), 0.05f);
  EXPECT_TRUE(mayHoldAStack(can_on_tin));
  Cloud tall_beside_low = *synthetic::box({0.06f, 0.06f, 0.16f}, {0.0f, 0.0f}, 0.0f, s);
  tall_beside_low += *synthetic::box({0.10f, 0.08f, 0.05f}, {0.08f, 0.0f}, 0.0f, s);
  EXPECT_TRUE(mayHoldAStack(tall_beside_low));

  EXPECT_FALSE(mayHoldAStack(*synthetic::box({0.20f, 0.10f, 0.12f}, {0.0f, 0.0f}, 0.4f, s)));
  EXPECT_FALSE(mayHoldAStack(*synthetic::box({0.06f, 0.06f, 0.05f}, {0.0f, 0.0f}, 0.0f, s)));
  EXPECT_FALSE(mayHoldAStack(*synthetic::roundObject(0.04f, 0.04f, 0.16f, {0.0f, 0.0f}, s)));
  EXPECT_FALSE(mayHoldAStack(*synthetic::roundObject(0.03f, 0.05f, 0.12f, {0.0f, 0.0f}, s)));
}

TEST(ClusterSplit, SingleObjectsStayWhole) {
  const CloudPtr objects[] = {
      synthetic::box({0.20f, 0.10f, 0.12f}, {0.0f, 0.0f}, 0.4f, synthetic::voxelGridSampler()),
      synthetic::box({0.06f, 0.06f, 0.05f}, {0.0f, 0.0f}, 0.0f, synthetic::voxelGridSampler()),
      synthetic::roundObject(0.04f, 0.04f, 0.16f, {0.0f, 0.0f}, synthetic::voxelGridSampler()),
      synthetic::roundObject(0.05f, 0.03f, 0.12f, {0.0f, 0.0f},
                             synthetic::voxelGridSampler()),  // cone
      // Neither the strips down a lying can's side nor the floor of a bowl seen within its rim
      // are top faces of objects of their own.
      synthetic::lyingCylinder(0.035f, 0.12f, {0.0f, 0.0f}, 0.3f, synthetic::voxelGridSampler()),
      synthetic::bowl(0.04f, 0.08f, 0.07f, 0.004f, {0.0f, 0.0f}, synthetic::voxelGridSampler()),
  };
  for (const CloudPtr& object : objects) {
    const std::vector<CloudPtr> parts = split(*object);
    ASSERT_EQ(parts.size(), 1u) << object->size() << " points";
    EXPECT_EQ(parts[0]->size(), object->size());
  }
}

TEST(ClusterSplit, FarBoxWithDepthStepsStaysWhole) {
  // 2 m away the depth steps (12 mm) lie farther apart than 6 mm voxels: the supervoxel graph
  // fell apart into terraces, and the box into four parts.
  synthetic::Sampler far = synthetic::voxelGridSampler();
  far.camera *= 2.0f;
  far.noise_sigma = 0.0f;  // the steps are the noise here
  const CloudPtr box = synthetic::box({0.235f, 0.127f, 0.242f}, {0.0f, 0.0f}, 0.3f, far);
  const std::vector<CloudPtr> parts = split(*box, far, true);
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0]->size(), box->size());
}

TEST(ClusterSplit, OpenCupWithHandleStaysWhole) {
  // Outer wall, the inside seen through the opening (concave seam at its bottom) and a handle.
  const float r = 0.04f, h = 0.10f, wall = 0.004f;
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  std::mt19937 rng(3);
  Cloud cup;
  const CloudPtr outer = synthetic::roundObject(r, r, h, {0.0f, 0.0f}, s);
  for (const auto& p : *outer) {
    if (p.z < h - 1e-4f || std::hypot(p.x, p.y) > r - wall) cup.push_back(p);  // no lid
  }
  // The inside wall, where the line of sight passes over the rim (the bottom inside is hidden).
  const float inner = r - wall;
  auto seenOverRim = [&](const Eigen::Vector3f& p) {
    for (float step = 0.002f; step < 1.0f; step += 0.002f) {
      const Eigen::Vector3f q = p + step * (s.camera - p).normalized();
      if (q.z() >= h) return true;
      if (q.head<2>().norm() > inner) return false;
    }
    return false;
  };
  for (float z = 0.01f; z <= h; z += s.spacing) {
    for (float t = 0.0f; t < 2 * kPi; t += s.spacing / inner) {
      const Eigen::Vector3f p(inner * std::cos(t), inner * std::sin(t), z);
      if (seenOverRim(p))
        synthetic::addIfVisible(p, {-std::cos(t), -std::sin(t), 0.0f}, s, rng, cup);
    }
  }
  for (float t = 0.0f; t < kPi; t += 0.05f) {  // handle: a half ring on the side
    for (float u = 0.0f; u < 2 * kPi; u += 0.6f) {
      const Eigen::Vector3f centre(r + 0.02f * std::sin(t), 0.0f, 0.05f + 0.03f * std::cos(t));
      const Eigen::Vector3f n(std::sin(t) * std::cos(u), std::sin(u), std::cos(t) * std::cos(u));
      synthetic::addIfVisible(centre + 0.006f * n, n, s, rng, cup);
    }
  }
  const size_t size = cup.size();
  const std::vector<CloudPtr> parts = split(cup);
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0]->size(), size);
}

// Points of `cloud` except those with x in [x0, x1] and y in [y0, y1] below `height`: a face
// in the 2 mm gap between two touching objects, hidden by the neighbour up to its top.
CloudPtr withoutGapFace(const CloudPtr& cloud, float x0, float x1, float y0, float y1,
                        float height) {
  auto out = std::make_shared<Cloud>();
  for (const auto& p : *cloud) {
    if (!(p.x >= x0 && p.x <= x1 && p.y >= y0 && p.y <= y1 && p.z < height)) out->push_back(p);
  }
  return out;
}

// Boxes 10 x 9 cm in a row away from the camera (along y), 2 mm apart, as the camera sees them:
// each one's front face is hidden below the top of the box in front of it.
std::vector<CloudPtr> touchingBoxes(const std::vector<float>& heights,
                                    const synthetic::Sampler& s = synthetic::voxelGridSampler()) {
  const float pitch = 0.092f, first = -pitch * (heights.size() - 1) / 2;
  std::vector<CloudPtr> boxes;
  for (size_t i = 0; i < heights.size(); ++i) {
    const float y = first + pitch * i, front = y - 0.045f;
    CloudPtr box = synthetic::box({0.10f, 0.09f, heights[i]}, {0.0f, y}, 0.0f, s);
    if (i > 0)
      box = withoutGapFace(box, -1.0f, 1.0f, front - 0.001f, front + 0.001f, heights[i - 1]);
    boxes.push_back(box);
  }
  return boxes;
}

Cloud together(const std::vector<CloudPtr>& objects) {
  Cloud scene;
  for (const CloudPtr& object : objects) scene += *object;
  return scene;
}

TEST(ClusterSplit, TouchingBoxesOfNearlyEqualHeightComeApart) {
  // The two back boxes' tops lie 1.8 cm apart: as pieces of one object's top they were joined
  // again (2 parts); they stand side by side, each over its own part of the table under its own
  // flat top, and stay apart.
  const std::vector<CloudPtr> boxes = touchingBoxes({0.07f, 0.11f, 0.128f});
  expectPartsMatch(split(together(boxes)), boxes);
}

// A box 10 x 9 cm and a can 9 cm across 2 mm beside it; the can's side in the gap is hidden
// below the box's top.
std::vector<CloudPtr> canBesideABox(float box_height, float can_height) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const CloudPtr box = synthetic::box({0.10f, 0.09f, box_height}, {0.0f, 0.0f}, 0.0f, s);
  CloudPtr can = synthetic::roundObject(0.045f, 0.045f, can_height, {0.097f, 0.0f}, s);
  can = withoutGapFace(can, 0.0f, 0.056f, -1.0f, 1.0f, box_height);
  return {box, can};
}

TEST(ClusterSplit, CanTouchingABoxComesApart) {
  const std::vector<CloudPtr> objects = canBesideABox(0.16f, 0.10f);
  expectPartsMatch(split(together(objects)), objects);
}

TEST(ClusterSplit, TouchingBoxesWithTopsWithinACentimetreComeApart) {
  // Tops 8 mm apart: no concave seam the split keeps parts them (kTopStep), the cluster cannot
  // hold a stack (every point lies under its top band), and the two stayed one object. Each
  // box's points lie under its own top face.
  const std::vector<CloudPtr> boxes = touchingBoxes({0.10f, 0.108f});
  EXPECT_FALSE(mayHoldAStack(together(boxes)));
  expectPartsMatch(split(together(boxes)), boxes);
}

// Depth noise as a Kinect's at 1.3 m: 3.5 mm per coordinate, which makes many of a top's 1 cm
// cells steep (spread over more than kTopFaceStep).
synthetic::Sampler noisyAt1300mm() {
  synthetic::Sampler s = synthetic::voxelGridSampler();
  s.camera *= 1.3f;
  s.noise_sigma = 0.0035f;
  return s;
}

TEST(ClusterSplit, NoisyTouchingBoxesComeApart) {
  // The lower box's top was no face: too few of its cells level (under kTopFaceFill), and the
  // boxes stayed one object; its noisy cells at its level fill it.
  const synthetic::Sampler s = noisyAt1300mm();
  const std::vector<CloudPtr> boxes = touchingBoxes({0.06f, 0.10f}, s);
  expectPartsMatch(split(together(boxes), s), boxes);
}

TEST(ClusterSplit, NoisyBoxTopStaysOneFace) {
  // Noisy cells cut the top apart into pieces at one level: the top face goes on across them
  // (with the noisy fill alone a piece became an object of its own in rendered paper scenes).
  const synthetic::Sampler s = noisyAt1300mm();
  const CloudPtr box = synthetic::box({0.175f, 0.12f, 0.10f}, {0.0f, 0.0f}, 0.4f, s);
  const std::vector<CloudPtr> parts = split(*box, s);
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0]->size(), box->size());
}

TEST(ClusterSplit, BoxesWithOneFrontFaceComeApart) {
  // Three boxes in a row across the camera's view, 2 mm apart: their front faces form one
  // plane, which LCCP does not cut; each side face is hidden below the neighbour's top.
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const float heights[] = {0.10f, 0.125f, 0.093f}, pitch = 0.102f;
  std::vector<CloudPtr> boxes;
  for (int i = 0; i < 3; ++i) {
    CloudPtr box = synthetic::box({0.10f, 0.09f, heights[i]}, {pitch * (i - 1), 0.0f}, 0.0f, s);
    for (int side : {-1, 1}) {
      const int neighbour = i + side;
      if (neighbour < 0 || neighbour > 2) continue;
      const float face = pitch * (i - 1) + side * 0.05f;
      box = withoutGapFace(box, face - 0.001f, face + 0.001f, -1.0f, 1.0f, heights[neighbour]);
    }
    boxes.push_back(box);
  }
  expectPartsMatch(split(together(boxes)), boxes);
}

TEST(ClusterSplit, CanTouchingABoxOfNearlyItsHeightComesApart) {
  const std::vector<CloudPtr> objects = canBesideABox(0.10f, 0.092f);
  expectPartsMatch(split(together(objects)), objects);
}

// Two cans of the same height 2 mm apart: one level region over both tops, whose outline
// narrows between the two circles (issue 15: same-height neighbours stayed one object).
TEST(ClusterSplit, TwoCansOfTheSameHeightComeApart) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const CloudPtr left = synthetic::roundObject(0.045f, 0.045f, 0.12f, {-0.046f, 0.0f}, s);
  const CloudPtr right = synthetic::roundObject(0.045f, 0.045f, 0.12f, {0.046f, 0.0f}, s);
  expectPartsMatch(split(together({left, right})), {left, right});
}

// A can beside a box of its own height: one level region over both tops, meeting along a short
// tangent that 1 cm cells fill in (saddle / peak 0.73, above kNeckRatio); it parts at the
// shallower neck into a lid and a box top (issue 15: the can stayed joined to the box). Within
// 15 %: the box takes ~10 % of the can's points along the tangent.
TEST(ClusterSplit, CanTouchingABoxOfItsOwnHeightComesApart) {
  for (float height : {0.08f, 0.12f}) {
    const std::vector<CloudPtr> objects = canBesideABox(height, height);
    expectPartsMatch(split(together(objects)), objects, 0.15f);
  }
}

// A box 20 x 9 cm stays one object: its top is a rectangle (a ridge of depths, no neck), and a
// box whose top holds a printed line (geometry only) has one level top.
TEST(ClusterSplit, LongBoxStaysWhole) {
  const CloudPtr box =
      synthetic::box({0.20f, 0.09f, 0.10f}, {0.0f, 0.0f}, 0.3f, synthetic::voxelGridSampler());
  const std::vector<CloudPtr> parts = split(*box);
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0]->size(), box->size());
}

// A block of 3 x 3 boxes 10 x 9 cm, 2 mm apart, tops 7-14 cm high, as the camera sees it: a box's
// sides facing a neighbour are hidden below the neighbour's top.
std::vector<CloudPtr> blockOfBoxes() {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const float heights[3][3] = {
      {0.08f, 0.12f, 0.10f}, {0.14f, 0.09f, 0.115f}, {0.07f, 0.13f, 0.10f}};
  const Eigen::Vector2f size(0.10f, 0.09f), pitch(0.102f, 0.092f);
  auto centre = [&](int r, int c) {
    return Eigen::Vector2f(pitch.x() * (c - 1), pitch.y() * (r - 1));
  };
  std::vector<CloudPtr> boxes;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const CloudPtr box =
          synthetic::box({size.x(), size.y(), heights[r][c]}, centre(r, c), 0.0f, s);
      auto seen = std::make_shared<Cloud>();
      for (const auto& p : *box) {
        bool hidden = false;
        for (int nr = 0; nr < 3; ++nr) {
          for (int nc = 0; nc < 3; ++nc) {
            const Eigen::Vector2f offset = p.getVector3fMap().head<2>() - centre(nr, nc);
            hidden |= (nr != r || nc != c) && std::abs(offset.x()) < size.x() / 2 + 0.003f &&
                      std::abs(offset.y()) < size.y() / 2 + 0.003f && p.z < heights[nr][nc];
          }
        }
        if (!hidden) seen->push_back(p);
      }
      boxes.push_back(seen);
    }
  }
  return boxes;
}

// Through the whole clustering (split and joins): every box of the block, each under a level top
// face of its own, is its own cluster. The joins of cluster_join.h took some for the inside of an
// open object or the hidden middle of one and joined them again.
TEST(ClusterSplit, BlockOfTouchingBoxesComesApartThroughTheJoins) {
  const std::vector<CloudPtr> boxes = blockOfBoxes();
  const SeenCluster seen = seenCluster(together(boxes));
  const std::vector<CloudPtr> clusters =
      extractClusters(seen.cluster, ClusteringParams(), &seen.table);
  expectPartsMatch(clusters, boxes, 0.15f);
}

// A box 12 x 24 x 5 cm lying across the middle of a box 30 x 16 x 6 cm (OSD learn19, learn21):
// the lower box's top shows left and right of the upper one, two level faces at one height. It
// is one box: what parts the faces lies on it. The lower box stays whole, in the same cluster as
// the upper one and alone in its own (the scene's points hand over the upper box).
struct BoxAcrossABox {
  CloudPtr lower_visible, upper;
};
// Off to the camera's right, so that the upper box's left face, standing on the lower top,
// joins them in one Euclidean cluster.
BoxAcrossABox boxAcrossABox() {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const float x = 0.12f;
  const CloudPtr lower = synthetic::box({0.30f, 0.16f, 0.06f}, {x, 0.0f}, 0.0f, s);
  const CloudPtr upper =
      synthetic::lifted(synthetic::box({0.12f, 0.24f, 0.05f}, {x, 0.0f}, 0.0f, s), 0.06f);
  return {synthetic::withoutFootprint(lower, x - 0.06f, x + 0.06f, -0.12f, 0.12f, 0.06f), upper};
}

TEST(ClusterSplit, BoxWithABoxAcrossItsTopStaysOneBox) {
  const BoxAcrossABox stack = boxAcrossABox();
  // Within 8 %: strips of the lower top along the upper box's sides (~120 points, 6 %) go with
  // the upper box; before, the lower box came in two parts of ~950 points each.
  expectPartsMatch(split(together({stack.lower_visible, stack.upper})),
                   {stack.lower_visible, stack.upper}, 0.08f);

  // The lower box alone in its cluster (the upper one parted from it by a gap in the samples):
  // the upper box comes with the scene's points.
  const SeenCluster lower = seenCluster(*stack.lower_visible);
  const SeenCluster upper = seenCluster(*stack.upper);
  auto scene = std::make_shared<Cloud>(*lower.cluster);
  *scene += *upper.cluster;
  EXPECT_EQ(
      splitAtConcaveSeams(lower.cluster, lower.table, ClusteringParams(), nullptr, scene).size(),
      1u);
  // Without it, nothing tells the two faces from two boxes of one height side by side.
  EXPECT_EQ(splitAtConcaveSeams(lower.cluster, lower.table, ClusteringParams()).size(), 2u);
}

// The clusters the pipeline fits from `scene` (table frame; camera of voxelGridSampler) and
// their fits: Euclidean clusters split with the table, then fitObjects, as Pipeline runs them.
std::vector<ShapeFit> fitted(const Cloud& scene) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const Eigen::Isometry3f camera_from_table = synthetic::cameraFromTable(s);
  auto cloud = std::make_shared<Cloud>(scene);
  synthetic::transformCloud(camera_from_table, *cloud);
  cloud->width = static_cast<uint32_t>(cloud->size());
  cloud->height = 1;
  const Plane table = synthetic::transformPlane(camera_from_table, synthetic::tablePlane());
  std::vector<CloudPtr> clusters = extractClusters(cloud, ClusteringParams(), &table);
  return fitObjects(ShapeEstimator(), table, ViewBounds(), clusters);
}

// Each fit a cube matching one of `boxes` (width, depth, height): its footprint edges within 2 %,
// its height within 5 % (a 4-6 cm height from the highest and lowest of points with 1 mm noise,
// or, resting on another object, from its own lowest 1 %: 1-2 mm off).
void expectBoxes(const std::vector<ShapeFit>& fits, std::vector<Eigen::Vector3f> boxes) {
  ASSERT_EQ(fits.size(), boxes.size());
  for (const ShapeFit& fit : fits) {
    ASSERT_TRUE(fit.ok && fit.type == ShapeType::Cube) << fit.reason;
    // The fit's z edge is along up (its axes: x, y on the table).
    std::array<float, 3> edges{std::max(fit.dimensions.x(), fit.dimensions.y()),
                               std::min(fit.dimensions.x(), fit.dimensions.y()),
                               fit.dimensions.z()};
    auto off = [&](const Eigen::Vector3f& box) {
      float worst = 0.0f;
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(edges[k] / box[k] - 1.0f) / (k < 2 ? 0.02f : 0.05f));
      return worst;  // 1: at the tolerance
    };
    const auto nearest = std::min_element(
        boxes.begin(), boxes.end(), [&](const auto& a, const auto& b) { return off(a) < off(b); });
    EXPECT_LE(off(*nearest), 1.0f) << "cube " << edges[0] << " x " << edges[1] << " x " << edges[2]
                                   << "; nearest box " << nearest->transpose();
    boxes.erase(nearest);
  }
}

// A plank 18 x 7 x 4 cm lying across two boxes 7 x 8 x 6 cm standing 6 cm apart (the rendered
// clutter's "box across two"): its ends 1 cm inside the legs' outer faces, its front face
// nearly flush with theirs. LCCP joins the pile into one convex part and the legs' tops are
// hidden under the plank (no top faces); slices under the plank fall into two pieces. Three
// boxes, each its own size, the plank fitted on the legs (its bottom 6 cm up), not the table.
TEST(ClusterSplit, BoxAcrossTwoBoxesComesApartIntoThree) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  Cloud scene;
  for (float side : {-1.0f, 1.0f}) {
    scene += *synthetic::withoutFootprint(
        synthetic::box({0.07f, 0.08f, 0.06f}, {side * 0.065f, 0.0f}, 0.0f, s), -0.09f, 0.09f,
        -0.035f, 0.035f, 0.06f);
  }
  scene += *synthetic::lifted(synthetic::box({0.18f, 0.07f, 0.04f}, {0.0f, 0.0f}, 0.0f, s), 0.06f);
  const std::vector<ShapeFit> fits = fitted(scene);
  expectBoxes(fits, {{0.08f, 0.07f, 0.06f}, {0.08f, 0.07f, 0.06f}, {0.18f, 0.07f, 0.04f}});
  // The plank rests on the legs: its centre 8 cm up, not 5 cm (fitted down to the table).
  const auto plank = std::max_element(fits.begin(), fits.end(), [](const auto& a, const auto& b) {
    return a.dimensions.maxCoeff() < b.dimensions.maxCoeff();
  });
  const Eigen::Isometry3f table_from_camera = synthetic::cameraFromTable(s).inverse();
  EXPECT_NEAR((table_from_camera * plank->center).z(), 0.08f, 0.004f);
}

// A box on a box: two boxes, each its own size.
TEST(ClusterSplit, BoxOnABoxIsFittedAsTwo) {
  const BoxOnBox stack = boxOnBox();
  expectBoxes(fitted(stack.scene), {{0.24f, 0.16f, 0.06f}, {0.16f, 0.10f, 0.05f}});
}

// A can lying on a box: its contact line is hidden under it, so no supervoxel seam joins the
// can's side to the box top; the can rests on the box's flat top and stays apart (rendered
// stacked scene 1765722565 lost it to the box).
TEST(ClusterSplit, CanLyingOnABoxStaysApart) {
  const synthetic::Sampler s = synthetic::voxelGridSampler();
  const CloudPtr lower = synthetic::box({0.24f, 0.16f, 0.06f}, {0.0f, 0.0f}, 0.0f, s);
  // The box top within 1 cm of the can and the can's side within 1.2 cm of the box top unseen
  // (the view from above hides the wedge around the contact line).
  Cloud scene = *synthetic::withoutFootprint(lower, -0.06f, 0.06f, -0.043f, 0.043f, 0.06f);
  for (const auto& p :
       *synthetic::lifted(synthetic::lyingCylinder(0.033f, 0.10f, {0.0f, 0.0f}, 0.0f, s), 0.06f)) {
    if (p.z > 0.072f) scene.push_back(p);
  }
  const std::vector<ShapeFit> fits = fitted(scene);
  ASSERT_EQ(fits.size(), 2u);  // 1 without the rule: the can and the box as one cube
  // The box 6 cm tall; the can on it 6.6 cm across (a lying cylinder, or a box around what is
  // seen of it: 5.6 cm), fitted on the box, not down to the table (12.6 cm).
  ASSERT_TRUE(fits[0].ok && fits[0].type == ShapeType::Cube);
  EXPECT_NEAR(fits[0].dimensions.z(), 0.06f, 0.003f);
  ASSERT_TRUE(fits[1].ok);
  const float can_height =
      fits[1].type == ShapeType::Cube ? fits[1].dimensions.z() : 2.0f * fits[1].radius;
  EXPECT_GT(can_height, 0.05f);
  EXPECT_LT(can_height, 0.075f);
}

TEST(ClusterSplit, DisabledOrWithoutTableNothingIsSplit) {
  const CloudPtr lower =
      synthetic::box({0.24f, 0.16f, 0.06f}, {0.0f, 0.0f}, 0.0f, synthetic::voxelGridSampler());
  auto scene = std::make_shared<Cloud>(
      *synthetic::withoutFootprint(lower, -0.08f, 0.1f, -0.06f, 0.08f, 0.06f));
  *scene += *synthetic::lifted(
      synthetic::box({0.16f, 0.10f, 0.05f}, {0.01f, 0.01f}, 0.3f, synthetic::voxelGridSampler()),
      0.06f);
  ClusteringParams off;
  off.split_concavity_deg = 0.0f;
  const Plane table = synthetic::tablePlane();
  EXPECT_EQ(splitAtConcaveSeams(scene, table, off).size(), 1u);
  EXPECT_EQ(extractClusters(scene, ClusteringParams()).size(), 1u);  // no table given
  EXPECT_EQ(splitAtConcaveSeams(CloudPtr(), table, ClusteringParams()).size(), 1u);
}

}  // namespace
}  // namespace tabletop_shapes
