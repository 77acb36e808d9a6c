// The whole pipeline on rendered Kinect-v1 scenes of the paper's four objects: every object is
// found, typed right, and measured well within the paper's errors (Tables 2-3).
#include "tabletop_shapes/core/pipeline.h"
#include "tabletop_shapes/sim/clutter_scenes.h"
#include "tabletop_shapes/sim/evaluation.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

using namespace tabletop_shapes;
using namespace tabletop_shapes::sim;

namespace {

struct Outcome {
  int objects = 0, detected = 0, typed_right = 0, false_positives = 0;
  std::map<std::string, std::vector<double>> errors;  // "object/measure" -> relative errors %
};

// Scene `index` (0-based) of `benchmark_accuracy --everyday --seed benchmark_seed` on `sensor`,
// rendered and run through the pipeline as the benchmark runs it (up as from tf2, the sensor's
// edge smear and near limit).
struct EverydayRun {
  RenderedScene scene;
  SceneResult result;
};
EverydayRun runEverydayScene(uint32_t benchmark_seed, int index, SensorModel sensor) {
  std::mt19937 seeds(benchmark_seed);  // benchmark_accuracy's everyday scene seeds
  for (int i = 0; i < index; ++i) seeds();
  EverydayRun run;
  run.scene = renderScene(everydayScene(static_cast<uint32_t>(seeds()), sensor));
  const NoiseModel& noise = run.scene.spec.noise;
  PipelineParams params;
  params.table.up = run.scene.up;
  if (noise.enabled && noise.edge_bleeding)
    params.shapes.edge_bleed_px = static_cast<float>(noise.edge_bleed_px);
  params.shapes.near_limit = noise.min_range;
  run.result = Pipeline(params).process(*run.scene.cloud);
  return run;
}

// The four objects in a 2 x 2 grid (well apart, so none hides another), cameras at 0.7-1.2 m.
Outcome runPaperScenes(int scenes, bool auto_up) {
  Outcome outcome;
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> distance(0.7f, 1.2f), tilt(30.0f, 55.0f), yaw(0.0f, 360.0f),
      object_yaw(0.0f, 3.1f);
  for (int i = 0; i < scenes; ++i) {
    SceneSpec spec = paperScene({distance(rng), tilt(rng), yaw(rng)}, NoiseModel(), 100 + i);
    const Eigen::Vector2f slots[] = {
        {-0.13f, -0.13f}, {-0.13f, 0.13f}, {0.13f, -0.13f}, {0.13f, 0.13f}};
    for (size_t k = 0; k < spec.objects.size(); ++k) {
      spec.objects[k].position_on_table = slots[(k + i) % 4];
      spec.objects[k].yaw = object_yaw(rng);
    }
    const RenderedScene scene = renderScene(spec);
    PipelineParams params;
    params.auto_up = auto_up;
    params.table.up = scene.up;
    const SceneResult result = Pipeline(params).process(*scene.cloud);
    EXPECT_TRUE(result.table.found) << "scene " << i << ": " << result.table.reason;

    const std::vector<Match> matches = matchByCenter(scene.objects, result.objects, 0.03);
    outcome.objects += static_cast<int>(scene.objects.size());
    outcome.detected += static_cast<int>(matches.size());
    outcome.false_positives += static_cast<int>(result.objects.size() - matches.size());
    for (const Match& m : matches) {
      const GroundTruthObject& truth = scene.objects[m.truth];
      const ShapeFit& fit = result.objects[m.detection];
      outcome.typed_right += fit.ok && fit.type == truth.type;
      for (const Measure& measure : compareToTruth(truth, fit)) {
        outcome.errors[truth.name + "/" + measure.name].push_back(measure.error_percent);
      }
    }
  }
  return outcome;
}

// Issue goal: at most half the paper's error, and at most 3 % on edges, radii and heights.
void expectWithinGoals(const Outcome& outcome) {
  const std::map<std::string, double> paper = {
      {"milk-tea box/length", 2.07},  {"milk-tea box/width", 3.78}, {"milk-tea box/height", 13.89},
      {"milk-tea box/volume", 15.72}, {"teapot box/length", 4.40},  {"teapot box/width", 4.62},
      {"teapot box/height", 4.96},    {"teapot box/volume", 11.82}, {"mug/radius", 24.14},
      {"mug/height", 3.83},           {"mug/volume", 40.22},        {"beaker/radius_bottom", 10.0},
      {"beaker/radius_top", 10.0},    {"beaker/height", 5.27},      {"beaker/volume", 15.22}};
  for (const auto& [measure, paper_error] : paper) {
    const auto found = outcome.errors.find(measure);
    ASSERT_NE(found, outcome.errors.end()) << measure << " never measured";
    const double median = percentile(found->second, 0.5);
    double goal = paper_error / 2;
    if (measure.find("volume") == std::string::npos) goal = std::min(goal, 3.0);
    EXPECT_LE(median, goal) << measure << ": median " << median << " % over "
                            << found->second.size() << " fits (paper " << paper_error << " %)";
  }
}

// Detection is held at the level measured now (29 / 32 objects, 2 false positives); the
// benchmark's goal of 99 % detection is not reached yet (benchmark_accuracy: 94.9 %).
TEST(PipelineOnRenderedScenes, PaperObjectsWithUpFromTf) {
  const Outcome outcome = runPaperScenes(8, false);
  EXPECT_GE(outcome.detected, outcome.objects - 3);
  EXPECT_EQ(outcome.typed_right, outcome.detected);
  EXPECT_LE(outcome.false_positives, 2);
  expectWithinGoals(outcome);
}

TEST(PipelineOnRenderedScenes, PaperObjectsWithUpEstimated) {
  const Outcome outcome = runPaperScenes(4, true);
  EXPECT_GE(outcome.detected, outcome.objects - 2);
  EXPECT_GE(outcome.typed_right, outcome.detected - 1);
  EXPECT_LE(outcome.false_positives, 1);
}

// The scene of benchmark_accuracy's default run (seed 2012: 40 paper scenes, then random ones)
// whose renderer seed is `seed`; its spec comes from the generators, as in the benchmark.
SceneSpec benchmarkScene(uint32_t seed) {
  std::mt19937 rng(2012);
  for (int i = 0; i < 100; ++i) {
    const SceneSpec spec = i < 40 ? jitteredPaperScene(rng) : randomScene(rng);
    if (spec.seed == seed) return spec;
  }
  ADD_FAILURE() << "benchmark scene " << seed << " not found: the benchmark's scenes changed";
  return SceneSpec();
}

// That scene through the pipeline, up given as the benchmark gives it (from tf2 on a robot).
struct BenchmarkRun {
  RenderedScene scene;
  SceneResult result;
  std::vector<Match> matches;
  std::vector<std::string> typed_right;  // truth names, sorted
};

BenchmarkRun runBenchmarkScene(uint32_t seed) {
  BenchmarkRun run;
  run.scene = renderScene(benchmarkScene(seed));
  PipelineParams params;
  params.table.up = run.scene.up;
  run.result = Pipeline(params).process(*run.scene.cloud);
  run.matches = matchByCenter(run.scene.objects, run.result.objects, 0.03);
  for (const Match& m : run.matches) {
    if (run.result.objects[m.detection].type == run.scene.objects[m.truth].type) {
      run.typed_right.push_back(run.scene.objects[m.truth].name);
    }
  }
  std::sort(run.typed_right.begin(), run.typed_right.end());
  return run;
}

// Benchmark scene 3107407257 (one milk-tea box seen from 1.46 m at 32 deg): a RANSAC sliver
// tilted 3.5 deg through stray points near the table, filling 5 % of its wide hull, had been
// taken for the support plane; the table and the box were lost.
TEST(PipelineOnRenderedScenes, FarTableIsNotLostToASliver) {
  const BenchmarkRun run = runBenchmarkScene(3107407257u);
  ASSERT_TRUE(run.result.table.found) << run.result.table.reason;
  EXPECT_NEAR(run.result.table.plane.d, run.scene.table_plane.d, 0.005f);
  EXPECT_GT(run.result.table.plane.normal.dot(run.scene.table_plane.normal),
            std::cos(degToRad(1.0f)));
  EXPECT_EQ(run.result.objects.size(), 1u);
  EXPECT_EQ(run.typed_right, std::vector<std::string>{"milk-tea box"});
}

// The teapot box stands 8 cm in front of the milk-tea box as the camera sees them; the flying
// pixels along the teapot box's edge filled the 18 cm depth jump and made one cluster of both
// (benchmark scene 698990783: both missed, a "cylinder" of radius 0.21 m found instead).
TEST(PipelineOnRenderedScenes, BoxesOneBehindTheOtherAreNotBridgedByFlyingPixels) {
  const BenchmarkRun run = runBenchmarkScene(698990783u);
  EXPECT_EQ(run.result.objects.size(), 4u);
  EXPECT_EQ(run.typed_right,
            (std::vector<std::string>{"beaker", "milk-tea box", "mug", "teapot box"}));
}

// The camera's near range (0.45 m) cuts the teapot box's nearest edge away; its top face and
// front face are then not adjacent surface patches and were two objects (benchmark scene
// 3776734038). The mug, mostly nearer than 0.45 m, is not expected.
TEST(PipelineOnRenderedScenes, BoxCutByTheNearRangeIsOneObject) {
  const BenchmarkRun run = runBenchmarkScene(3776734038u);
  EXPECT_EQ(run.result.objects.size(), 3u);
  EXPECT_EQ(run.typed_right, (std::vector<std::string>{"beaker", "milk-tea box", "teapot box"}));
}

// A RealSense D435 (edge smear 3 px, depth sigma 4 mm at 1 m) at 0.9 m, 50 deg down: an 18 mm
// marker between two bottles. The smear widened the marker's points to 30-36 mm (a cylinder up
// to 46 mm across) unless shapes.edge_bleed_px leaves it out; the split cut each bottle's neck
// off at the shoulder (a false cylinder on a short body) unless the neck joins its body again.
TEST(PipelineOnRenderedScenes, RealSenseMarkerIsThinAndBottlesKeepTheirNecks) {
  for (uint32_t seed : {11u, 12u, 13u}) {
    SceneSpec spec;
    setSensor(spec, SensorModel::RealSenseD435);
    spec.seed = seed;
    spec.placement.distance = 0.9f;
    spec.placement.tilt_deg = 50.0f;
    spec.placement.yaw_deg = 30.0f * static_cast<float>(seed);
    spec.placement.fixed_look_at = true;
    const Eigen::Vector2f across(-std::sin(degToRad(spec.placement.yaw_deg)),
                                 std::cos(degToRad(spec.placement.yaw_deg)));
    ObjectSpec marker = everydayObject(EverydayKind::Marker, 0);
    ObjectSpec small_bottle = everydayObject(EverydayKind::Bottle, 0);
    ObjectSpec large_bottle = everydayObject(EverydayKind::Bottle, 1);
    small_bottle.position_on_table = -0.16f * across;
    large_bottle.position_on_table = 0.16f * across;
    spec.objects = {marker, small_bottle, large_bottle};
    const RenderedScene scene = renderScene(spec);
    PipelineParams params;
    params.table.up = scene.up;
    params.shapes.edge_bleed_px = 3.0f;
    const SceneResult result = Pipeline(params).process(*scene.cloud);

    const std::vector<Match> matches = matchByCenter(scene.objects, result.objects, 0.03);
    EXPECT_EQ(matches.size(), 3u) << "seed " << seed;
    EXPECT_EQ(result.objects.size(), 3u) << "seed " << seed << ": a neck apart from its bottle?";
    for (const Match& m : matches) {
      const GroundTruthObject& truth = scene.objects[m.truth];
      const ShapeFit& fit = result.objects[m.detection];
      EXPECT_TRUE(fit.ok && fit.type == ShapeType::Cylinder)
          << "seed " << seed << " " << truth.name << ": " << shapeTypeName(fit.type) << " "
          << fit.reason;
      // The smear left within half a voxel of the marker's sides widens it by 2-3 mm (the
      // benchmark's RealSense markers: r 10.3-14.7 mm for 9 mm; 12-46 mm before).
      const float radius_tolerance = truth.name == "marker" ? 0.0035f : 0.004f;
      EXPECT_NEAR(fit.radius, truth.radius_bottom, radius_tolerance)
          << "seed " << seed << " " << truth.name;
      EXPECT_NEAR(fit.height, truth.height, 0.05f * truth.height)
          << "seed " << seed << " " << truth.name;
    }
  }
}

// Issue 12's "no fitted solid more than 20 % larger than the object", on two RealSense everyday
// scenes of the benchmark (benchmark_accuracy --everyday, seed 2012: scenes 16 and 36):
// - a mug at 1.16 m: a cylinder lying across its handle and edge smear (r 49 mm, 12 cm wide in
//   view for points 8.4 cm wide) explained its points better than the upright one and came out
//   20.3 % over; a lying solid wider than its points across the line of sight is now rejected;
// - a box (89 x 38 x 175 mm) cut by the image's bottom border, seen from nearly straight above
//   at 0.46 m, only its top face in view: the smear all around that face made it 46 mm across
//   for 38 (20.4 % over); its hidden ends now move in by the smear.
TEST(PipelineOnRenderedScenes, RealSenseEverydaySolidsAreNoWiderThanTheObjects) {
  std::mt19937 seeds(2012);  // benchmark_accuracy's everyday scene seeds
  std::vector<uint32_t> scene_seeds;
  for (int i = 0; i < 36; ++i) scene_seeds.push_back(static_cast<uint32_t>(seeds()));
  const std::map<uint32_t, std::string> cases = {{scene_seeds[15], "border box"},
                                                 {scene_seeds[35], "mug"}};
  for (const auto& [seed, name] : cases) {
    const RenderedScene scene = renderScene(everydayScene(seed, SensorModel::RealSenseD435));
    PipelineParams params;
    params.table.up = scene.up;
    params.shapes.edge_bleed_px = static_cast<float>(scene.spec.noise.edge_bleed_px);
    const SceneResult result = Pipeline(params).process(*scene.cloud);
    const std::vector<Match> matches = matchByCenter(scene.objects, result.objects, 0.1);
    const auto m = std::find_if(matches.begin(), matches.end(), [&](const Match& m) {
      return scene.objects[m.truth].name == name;
    });
    ASSERT_NE(m, matches.end()) << name << " not found";
    const GroundTruthObject& truth = scene.objects[m->truth];
    const ShapeFit& fit = result.objects[m->detection];
    EXPECT_TRUE(expectedSolid(truth, fit, scene.up))
        << name << ": " << shapeTypeName(fit.type) << " " << fit.reason;
    EXPECT_LT(oversizePercent(truth, fit, scene.up), 15.0) << name;
    if (name == "mug") {
      EXPECT_GT(std::abs(fit.axis().dot(scene.up)), 0.9f) << "the mug stands";
      EXPECT_NEAR(fit.radius, truth.radius_bottom, 0.003f);
    } else {
      EXPECT_TRUE(fit.truncated);
      EXPECT_LT(fit.dimensions.minCoeff(), 0.044f) << "38 mm thick, 46 mm before";
    }
  }
}

// Issue 12's "cans must come out cylinders", on a RealSense everyday scene of the benchmark
// (seed 2012, scene 14): a short wide can (d 85, h 33 mm) at 1.06 m and a soup can (d 66, h
// 101 mm) at 0.55 m were typed box: the circle through their few wall points came out 2-3 mm
// small, and the box around the smeared lid explained the points better (0.7-1.4 mm RMS against
// 1.0-1.6). The box's empty top corners (the camera saw the table through them) now give them
// to the cylinder standing inside the box.
TEST(PipelineOnRenderedScenes, RealSenseCansAreCylinders) {
  const EverydayRun run = runEverydayScene(2012, 13, SensorModel::RealSenseD435);
  const RenderedScene& scene = run.scene;
  const SceneResult& result = run.result;
  const std::vector<Match> matches = matchByCenter(scene.objects, result.objects, 0.1);
  int cans = 0;
  for (const Match& m : matches) {
    const GroundTruthObject& truth = scene.objects[m.truth];
    const ShapeFit& fit = result.objects[m.detection];
    if (truth.name == "flat bottle" || truth.name == "border box") {
      EXPECT_EQ(fit.type, ShapeType::Cube) << truth.name << " stays a box";
      continue;
    }
    if (truth.name != "short wide can" && truth.name != "soup can") continue;
    ++cans;
    EXPECT_TRUE(expectedSolid(truth, fit, scene.up))
        << truth.name << ": " << shapeTypeName(fit.type);
    EXPECT_NEAR(fit.radius, truth.radius_bottom, 0.004f) << truth.name;
    EXPECT_NEAR(fit.height, truth.height, 0.005f) << truth.name;
  }
  EXPECT_EQ(cans, 2);
}

// Issue 12's false positives: a flattened bottle's round cap, standing on its shoulder and
// widened by edge smear, parted the shoulder into two level faces of one height, and the bottle
// came out as two boxes 23 cm high (benchmark_accuracy --everyday, seed 2012: RealSense scenes 6
// and 15, Kinect scene 39). The cap rests on both faces: one box, and nothing else near it.
TEST(PipelineOnRenderedScenes, FlatBottleIsNotHalvedByItsCap) {
  const std::vector<std::pair<int, SensorModel>> cases = {{5, SensorModel::RealSenseD435},
                                                          {14, SensorModel::RealSenseD435},
                                                          {38, SensorModel::KinectV1}};
  for (const auto& [index, sensor] : cases) {
    const EverydayRun run = runEverydayScene(2012, index, sensor);
    const RenderedScene& scene = run.scene;
    const SceneResult& result = run.result;
    const auto bottle = std::find_if(scene.objects.begin(), scene.objects.end(),
                                     [](const auto& o) { return o.name == "flat bottle"; });
    ASSERT_NE(bottle, scene.objects.end());
    int near = 0;
    for (const ShapeFit& fit : result.objects) {
      if ((fit.center - bottle->center).norm() > 0.1f) continue;
      ++near;
      EXPECT_EQ(fit.type, ShapeType::Cube) << sensorName(sensor) << " scene " << index;
      EXPECT_GT(fit.dimensions.head<2>().maxCoeff(), 0.9f * bottle->dimensions.head<2>().maxCoeff())
          << sensorName(sensor) << " scene " << index << ": half a bottle";
    }
    EXPECT_EQ(near, 1) << sensorName(sensor) << " scene " << index;
  }
}

// Issue 12's "never more than 20 % larger", on a Kinect everyday scene of the benchmark (seed 7,
// scene 8): a box cut by the image border stood behind a flattened bottle, as high as its cap,
// and the lines of sight to it crossed the cap's height over the bottle's shoulder: it was
// joined to the bottle as the inside of an open object, and the two came out one cylinder
// r 49 mm (102 % over the bottle's 50 mm). The opening is what a rim surrounds, not a cap.
TEST(PipelineOnRenderedScenes, BoxBehindAFlatBottleIsNotItsInside) {
  const EverydayRun run = runEverydayScene(7, 7, SensorModel::KinectV1);
  const RenderedScene& scene = run.scene;
  const SceneResult& result = run.result;
  const std::vector<Match> matches = matchByCenter(scene.objects, result.objects, 0.1);
  int checked = 0;
  for (const Match& m : matches) {
    const GroundTruthObject& truth = scene.objects[m.truth];
    if (truth.name != "flat bottle" && truth.name != "border box") continue;
    ++checked;
    const ShapeFit& fit = result.objects[m.detection];
    EXPECT_EQ(fit.type, ShapeType::Cube) << truth.name << ": " << shapeTypeName(fit.type);
    EXPECT_LT(oversizePercent(truth, fit, scene.up), 20.0) << truth.name;
  }
  EXPECT_EQ(checked, 2) << "the bottle and the box, each found";
}

// Issue 12's "a box cut by the border is never round": a Kinect border box at 0.51 m (benchmark
// seed 7, scene 24) of which only 102 points along the bottom border were seen came out a lying
// cylinder r 88 mm (99 % over): its visible arc bowed 1.8 mm out of its chord, its points 1.3 mm
// RMS off the wall. A flat face seen partly is no evidence of roundness.
TEST(PipelineOnRenderedScenes, BorderBoxSeenAlongTheBorderIsNotRound) {
  const EverydayRun run = runEverydayScene(7, 23, SensorModel::KinectV1);
  const std::vector<Match> matches = matchByCenter(run.scene.objects, run.result.objects, 0.1);
  int checked = 0;
  for (const Match& m : matches) {
    const GroundTruthObject& truth = run.scene.objects[m.truth];
    if (truth.name != "border box") continue;
    ++checked;
    const ShapeFit& fit = run.result.objects[m.detection];
    EXPECT_EQ(fit.type, ShapeType::Cube) << shapeTypeName(fit.type) << " r " << fit.radius;
    EXPECT_TRUE(fit.truncated);
    EXPECT_LT(oversizePercent(truth, fit, run.scene.up), 20.0);
  }
  EXPECT_EQ(checked, 1);
}

// Short wide cans (d 85, h 33 mm) seen over their lids: too few wall points for a round fit of
// their own, they came out boxes with 3-4 of their top corners empty (benchmark seed 7: Kinect
// scene 33, RealSense scenes 15 and 17). Their lid's points lie within the circle inscribed in the
// box: that cylinder is the can.
TEST(PipelineOnRenderedScenes, ShortWideCansUnderEmptyCornersAreCylinders) {
  const std::vector<std::pair<int, SensorModel>> cases = {{32, SensorModel::KinectV1},
                                                          {14, SensorModel::RealSenseD435},
                                                          {16, SensorModel::RealSenseD435}};
  for (const auto& [index, sensor] : cases) {
    const EverydayRun run = runEverydayScene(7, index, sensor);
    const std::vector<Match> matches = matchByCenter(run.scene.objects, run.result.objects, 0.1);
    int cans = 0;
    for (const Match& m : matches) {
      const GroundTruthObject& truth = run.scene.objects[m.truth];
      if (truth.name != "short wide can") continue;
      ++cans;
      const ShapeFit& fit = run.result.objects[m.detection];
      const std::string what = sensorName(sensor) + std::string(" scene ") + std::to_string(index);
      ASSERT_EQ(fit.type, ShapeType::Cylinder) << what;
      EXPECT_NEAR(fit.radius, truth.radius_bottom, 0.005f) << what;
      EXPECT_NEAR(fit.height, truth.height, 0.003f) << what;
      EXPECT_GT(std::abs(fit.axis().dot(run.scene.up)), 0.99f) << what;  // standing
    }
    EXPECT_EQ(cans, 1) << sensorName(sensor) << " scene " << index;
  }
}

// Covered table (benchmark_accuracy --clutter, scene 306266018): two boxes 9.2 cm tall stand
// side by side 5-10 mm apart, their tops one level rectangle (no neck). They were one
// `cube 0.205 x 0.096 x 0.091`: the straight empty gap between the tops now parts them, and the
// two faces are not joined again as halves of one top cut by an object lying across it. Each is
// found within 5 mm, at most 11 cm long.
TEST(PipelineOnRenderedScenes, CoveredTableBoxesOfOneHeightAGapApartAreTwo) {
  const RenderedScene scene = renderScene(clutterScene(ClutterKind::Covered, 306266018u));
  PipelineParams params;
  params.table.up = scene.up;
  params.shapes.near_limit = scene.spec.noise.min_range;
  const SceneResult result = Pipeline(params).process(*scene.cloud);
  const std::vector<Match> matches = matchByCenter(scene.objects, result.objects, 0.06);
  for (const int box : {6, 12}) {
    const GroundTruthObject& truth = scene.objects[box];
    ASSERT_EQ(truth.type, ShapeType::Cube);
    ASSERT_NEAR(truth.dimensions.z(), 0.092f, 0.001f);
    const auto match = std::find_if(matches.begin(), matches.end(),
                                    [&](const Match& m) { return m.truth == box; });
    ASSERT_NE(match, matches.end()) << "box " << box << " missed";
    EXPECT_LT(match->center_distance, 0.005) << "box " << box;
    const ShapeFit& fit = result.objects[match->detection];
    EXPECT_LT(fit.dimensions.maxCoeff(), 0.11f) << "box " << box;
  }
}

}  // namespace
