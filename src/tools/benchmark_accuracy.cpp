// benchmark_accuracy: the paper's Tables 2-3 and Fig. 12 on rendered Kinect scenes, plus
// segmentation scores on real labelled OSD scenes.
//   benchmark_accuracy [--paper-scenes N] [--random-scenes N] [--seed S] [--up auto]
//                      [--osd DIR] [--osd-up auto|labelled] [--out DIR] [--no-plots] [--verbose]
//                      [--save-failures DIR]
//                      [--everyday-scenes N] [--everyday N] [--sensor kinect|realsense]
//                      [--clutter-scenes N] [--clutter N] [--clutter-kind KIND]
//                      [--clutter-seeds S1,S2,...]
//                      [--set stage.name=value ...]   (parameters as in estimate_shapes)
// plus everyday objects (issue 12) on a Kinect v1 and a RealSense D435; --everyday N runs only
// that part, with N scenes per sensor; and rendered clutter (issue 15): --clutter N runs only
// that part, with N scenes per kind; --clutter-kind only one kind (covered: also with the camera
// height known), --clutter-seeds those scenes (the seeds --verbose prints) instead of N drawn.
#include "tabletop_shapes/core/parameter_table.h"
#include "tabletop_shapes/core/pipeline.h"
#include "tabletop_shapes/sim/clutter_scenes.h"
#include "tabletop_shapes/sim/evaluation.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

using namespace tabletop_shapes;
using namespace tabletop_shapes::sim;
namespace fs = std::filesystem;

namespace {

struct Options {
  int paper_scenes = 40;
  int random_scenes = 60;
  uint32_t seed = 2012;
  bool auto_up = false;
  std::string osd_dir;
  // OSD scenes: "up" from the plane of the points labelled table (as tf2 would give it)
  // instead of estimated from the scene.
  bool osd_labelled_up = false;
  std::string out_dir = "benchmark-output";
  bool plots = true;
  bool verbose = false;  // per scene: every true object and every detection
  // Scenes with a missed object or a false positive: <dir>/scene_<seed>.pcd + .json, to be
  // looked at with estimate_shapes --verbose.
  std::string failures_dir;
  int everyday_scenes = 40;             // per sensor, after the other parts; 0: none
  bool everyday_only = false;           // --everyday N: only the everyday part
  int clutter_scenes = 8;               // per clutter kind, after the rendered tables; 0: none
  bool clutter_only = false;            // --clutter N: only the clutter part
  int clutter_kind = -1;                // --clutter-kind: only this ClutterKind; -1: all
  std::vector<uint32_t> clutter_seeds;  // --clutter-seeds: these scenes instead of drawn ones
  std::vector<SensorModel> sensors = {SensorModel::KinectV1, SensorModel::RealSenseD435};
  PipelineParams params;  // defaults, changed by --set stage.name=value
};

// The paper's Tables 2-3: relative error [%] per object and measure.
const std::map<std::string, std::map<std::string, double>> kPaperErrors = {
    {"milk-tea box", {{"length", 2.07}, {"width", 3.78}, {"height", 13.89}, {"volume", 15.72}}},
    {"teapot box", {{"length", 4.40}, {"width", 4.62}, {"height", 4.96}, {"volume", 11.82}}},
    {"mug", {{"radius", 24.14}, {"height", 3.83}, {"volume", 40.22}}},
    {"beaker",
     {{"radius_bottom", 10.0}, {"radius_top", 10.0}, {"height", 5.27}, {"volume", 15.22}}}};
constexpr int kMinVisiblePixels = 200;
const char* kPaperObjects[] = {"milk-tea box", "teapot box", "mug", "beaker"};

// One true object as the pipeline saw it.
struct Sample {
  std::string name;
  ShapeType truth_type = ShapeType::Unknown;
  ShapeType found_type = ShapeType::Unknown;  // Unknown: unfitted or missed
  bool detected = false;
  double range = 0.0;  // camera to the object's centre [m]
  int faces_seen = 0;
  int visible_pixels = 0;
  // Counted for detection: enough pixels, and enough surface for the pipeline's settings.
  bool observable = false;
  std::vector<Measure> measures;
  double volume_estimate = 0.0, volume_truth = 0.0;
  GroundTruthObject truth;
  ShapeFit fit;                                   // when detected
  Eigen::Vector3f up = Eigen::Vector3f::UnitZ();  // the scene's, in the camera frame
};

// "stage.name=value" (names as in `estimate_shapes --parameters`); exits 2 when invalid.
void setFromText(const std::string& text, PipelineParams& params) {
  const size_t dot = text.find('.'), equals = text.find('=');
  std::string error = "expected stage.name=value";
  if (dot != std::string::npos && equals != std::string::npos && dot < equals) {
    try {
      error.clear();  // setParameter reports through it
      if (setParameter(params, text.substr(0, dot), text.substr(dot + 1, equals - dot - 1),
                       std::stod(text.substr(equals + 1)), error)) {
        return;
      }
    } catch (const std::exception&) {
      error = "the value is not a number";
    }
  }
  std::fprintf(stderr, "benchmark_accuracy: --set %s: %s\n", text.c_str(), error.c_str());
  std::exit(2);
}

void progress(int done, int total) {
  const int width = 40, filled = total ? done * width / total : width;
  std::fprintf(stderr, "\r[%s%s] %d/%d scenes", std::string(filled, '#').c_str(),
               std::string(width - filled, '.').c_str(), done, total);
  if (done == total) std::fprintf(stderr, "\n");
}

struct Tally {
  std::vector<Sample> samples;
  int false_positives = 0;
  int pieces = 0;  // of the false positives: centred within a true object's bounding sphere + 3 cm
  int scenes_without_table = 0;
  std::vector<double> frame_ms;
};

// Occupied voxels (edge `leaf`) of each object's valid pixels at least `min_height` above the
// table: what the voxel grid and the table's noise band leave for clustering. An object cut by
// the image border or by the sensor's minimum range can keep hundreds of pixels yet cover fewer
// voxels than the smallest cluster the pipeline accepts (a beaker at 0.42 m: 431 px).
std::vector<int> occupiedVoxels(const RenderedScene& scene, float leaf, float min_height) {
  std::vector<std::set<std::tuple<int, int, int>>> voxels(scene.objects.size());
  for (size_t i = 0; i < scene.labels.size(); ++i) {
    const int label = scene.labels[i];
    if (label < 0 || label >= static_cast<int>(voxels.size())) continue;
    const Eigen::Vector3f p = (*scene.cloud)[i].getVector3fMap();
    if (!p.allFinite() || scene.table_plane.signedDistance(p) < min_height) continue;
    const Eigen::Vector3i key = (p / std::max(leaf, 1e-4f)).array().floor().cast<int>();
    voxels[label].insert({key.x(), key.y(), key.z()});
  }
  std::vector<int> counts;
  for (const auto& set : voxels) counts.push_back(static_cast<int>(set.size()));
  return counts;
}

void printScene(const RenderedScene& scene, const SceneResult& result,
                const std::vector<Match>& matches, const std::vector<int>& voxels) {
  auto fitText = [](const ShapeFit& f) {
    char text[200];
    if (!f.ok) {
      std::snprintf(text, sizeof text, "unknown (%d points): %s", f.points, f.reason.c_str());
    } else if (f.type == ShapeType::Cube) {
      std::snprintf(text, sizeof text, "cube %.3f x %.3f x %.3f faces %d", f.dimensions.x(),
                    f.dimensions.y(), f.dimensions.z(), f.faces_seen);
    } else {
      std::snprintf(text, sizeof text, "%s r %.4f-%.4f h %.3f", shapeTypeName(f.type),
                    f.type == ShapeType::Cone ? f.radius_bottom : f.radius,
                    f.type == ShapeType::Cone ? f.radius_top : f.radius, f.height);
    }
    return std::string(text);
  };
  std::printf("scene seed %u: distance %.2f tilt %.0f yaw %.0f; table %s (%d inliers)\n",
              scene.spec.seed, scene.spec.placement.distance, scene.spec.placement.tilt_deg,
              scene.spec.placement.yaw_deg, result.table.found ? "found" : "NOT found",
              result.table.inliers);
  std::vector<bool> matched(result.objects.size());
  for (size_t t = 0; t < scene.objects.size(); ++t) {
    const GroundTruthObject& o = scene.objects[t];
    std::printf("  truth %-15s at %6.3f %6.3f %6.3f (%5d px, %4d voxels) -> ", o.name.c_str(),
                o.center.x(), o.center.y(), o.center.z(), o.visible_pixels, voxels[t]);
    const auto m = std::find_if(matches.begin(), matches.end(),
                                [&](const Match& m) { return m.truth == static_cast<int>(t); });
    if (m == matches.end()) {
      std::printf("MISSED\n");
      continue;
    }
    matched[m->detection] = true;
    std::printf("%s (%.1f mm off)\n", fitText(result.objects[m->detection]).c_str(),
                1000 * m->center_distance);
  }
  for (size_t d = 0; d < result.objects.size(); ++d) {
    if (matched[d]) continue;
    const ShapeFit& f = result.objects[d];
    std::printf("  FALSE POSITIVE at %6.3f %6.3f %6.3f: %s\n", f.center.x(), f.center.y(),
                f.center.z(), fitText(f).c_str());
  }
  for (const RejectedCluster& r : result.rejected) {
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (const auto& p : r.points->points) centroid += p.getVector3fMap();
    centroid /= static_cast<float>(std::max<size_t>(r.points->size(), 1));
    std::printf("  rejected cluster at %6.3f %6.3f %6.3f, %zu points: %s\n", centroid.x(),
                centroid.y(), centroid.z(), r.points->size(), r.reason.c_str());
  }
}

// Radius of the sphere around a true object's centre that holds the object.
float boundingRadius(const GroundTruthObject& o) {
  if (o.type == ShapeType::Cube) return 0.5f * o.dimensions.norm();
  return std::hypot(std::max(o.radius_bottom, o.radius_top), 0.5f * o.height);
}

// Unmatched detections centred within some true object's bounding sphere grown by 3 cm: a part
// of an object found apart from the rest (the rest are junk).
int piecesAmong(const std::vector<GroundTruthObject>& truth, const std::vector<ShapeFit>& found,
                const std::vector<Match>& matches) {
  int pieces = 0;
  for (size_t d = 0; d < found.size(); ++d) {
    if (std::any_of(matches.begin(), matches.end(),
                    [&](const Match& m) { return m.detection == static_cast<int>(d); })) {
      continue;
    }
    pieces += std::any_of(truth.begin(), truth.end(), [&](const GroundTruthObject& o) {
      return (found[d].center - o.center).norm() <= boundingRadius(o) + 0.03f;
    });
  }
  return pieces;
}

// A detection belongs to the true object whose centre is nearest, within `match_distance`.
// camera_height_known: table.camera_height from the truth, as a robot would know it.
void runScene(const SceneSpec& spec, const Options& options, Tally& tally,
              double match_distance = 0.06, bool camera_height_known = false) {
  const RenderedScene scene = renderScene(spec);
  PipelineParams params = options.params;
  params.auto_up = options.auto_up;
  params.table.up = scene.up;  // what tf2 would give a robot
  // The camera's edge smear, as a robot's configuration for its camera would give it.
  if (spec.noise.enabled && spec.noise.edge_bleeding && params.shapes.edge_bleed_px == 0.0f)
    params.shapes.edge_bleed_px = static_cast<float>(spec.noise.edge_bleed_px);
  if (params.shapes.near_limit == 0.0f) params.shapes.near_limit = spec.noise.min_range;
  if (camera_height_known) params.table.camera_height = scene.table_plane.d;
  Pipeline pipeline(params);
  const SceneResult result = pipeline.process(*scene.cloud);
  tally.frame_ms.push_back(result.times.total_ms);
  if (!result.table.found) ++tally.scenes_without_table;

  const std::vector<Match> matches = matchByCenter(scene.objects, result.objects, match_distance);
  const std::vector<int> voxels =
      occupiedVoxels(scene, params.preprocess.leaf_size, params.table.min_height);
  std::vector<int> detection_of(scene.objects.size(), -1);
  for (const Match& m : matches) detection_of[m.truth] = m.detection;
  const int false_positives = static_cast<int>(result.objects.size() - matches.size());
  tally.false_positives += false_positives;
  tally.pieces += piecesAmong(scene.objects, result.objects, matches);
  if (options.verbose) printScene(scene, result, matches, voxels);
  const bool missed = std::count(detection_of.begin(), detection_of.end(), -1) > 0;
  const bool wrong_type = std::any_of(matches.begin(), matches.end(), [&](const Match& m) {
    const ShapeFit& fit = result.objects[m.detection];
    return !fit.ok || fit.type != scene.objects[m.truth].type;
  });
  if (!options.failures_dir.empty() && (missed || wrong_type || false_positives > 0)) {
    const std::string prefix =
        (fs::path(options.failures_dir) / ("scene_" + std::to_string(spec.seed))).string();
    if (!writePcd(scene, prefix + ".pcd") || !writeGroundTruthJson(scene, prefix + ".json")) {
      std::fprintf(stderr, "benchmark_accuracy: cannot write %s.pcd/.json\n", prefix.c_str());
    }
  }
  for (size_t t = 0; t < scene.objects.size(); ++t) {
    const GroundTruthObject& truth = scene.objects[t];
    Sample sample;
    sample.name = truth.name;
    sample.truth_type = truth.type;
    sample.range = truth.center.norm();
    sample.visible_pixels = truth.visible_pixels;
    sample.observable =
        truth.visible_pixels >= kMinVisiblePixels && voxels[t] >= params.clustering.min_size;
    sample.volume_truth = volume(truth);
    sample.truth = truth;
    sample.up = scene.up;
    if (detection_of[t] >= 0) {
      const ShapeFit& fit = result.objects[detection_of[t]];
      sample.fit = fit;
      sample.detected = true;
      sample.found_type = fit.ok ? fit.type : ShapeType::Unknown;
      sample.faces_seen = fit.faces_seen;
      sample.measures = compareToTruth(truth, fit);
      sample.volume_estimate = volume(fit);
    }
    tally.samples.push_back(sample);
  }
}

std::vector<double> errorsOf(const std::vector<const Sample*>& samples,
                             const std::function<bool(const Measure&)>& wanted) {
  std::vector<double> errors;
  for (const Sample* s : samples) {
    for (const Measure& m : s->measures) {
      if (wanted(m)) errors.push_back(m.error_percent);
    }
  }
  return errors;
}

bool isVolume(const Measure& m) { return m.name == "volume"; }
bool isDimension(const Measure& m) { return m.name != "volume"; }

void printPaperTable(const Tally& tally) {
  std::printf(
      "\nThe paper's objects at 0.6-1.2 m: relative error (eq. 17), median and 90th percentile"
      "\n(box edges sorted length >= width >= height; goal: median <= 2 %% on dimensions, <= 5 %%"
      " on volume)\n\n");
  std::printf("%-13s %-14s %5s %9s %9s %9s  %s\n", "object", "measure", "n", "median", "p90",
              "paper", "goal");
  for (const char* object : kPaperObjects) {
    std::vector<const Sample*> near;
    for (const Sample& s : tally.samples) {
      if (s.name == object && s.range >= 0.6 && s.range < 1.2) near.push_back(&s);
    }
    // The paper's column order: edges or radii, height, volume.
    for (const char* name :
         {"length", "width", "radius", "radius_bottom", "radius_top", "height", "volume"}) {
      if (!kPaperErrors.at(object).count(name)) continue;
      const std::vector<double> errors =
          errorsOf(near, [&](const Measure& m) { return m.name == name; });
      const double median = percentile(errors, 0.5), p90 = percentile(errors, 0.9);
      const double goal = std::string(name) == "volume" ? 5.0 : 2.0;
      std::printf("%-13s %-14s %5zu %8.2f%% %8.2f%% %8.2f%%  %s\n", object, name, errors.size(),
                  median, p90, kPaperErrors.at(object).at(name),
                  errors.empty() ? "-" : (median <= goal ? "met" : "MISSED"));
    }
  }
}

void printDetection(const Tally& tally) {
  const std::vector<ShapeType> types = {ShapeType::Cube, ShapeType::Cylinder, ShapeType::Cone};
  std::map<ShapeType, std::map<std::string, int>> confusion;
  int detected = 0, right = 0, counted = 0;
  for (const Sample& s : tally.samples) {
    if (!s.observable) continue;  // hidden behind another object, out of view or out of range
    ++counted;
    detected += s.detected;
    right += s.detected && s.found_type == s.truth_type;
    confusion[s.truth_type][s.detected ? shapeTypeName(s.found_type) : "missed"]++;
  }
  std::printf(
      "\nDetection and type, every object with >= %d visible pixels covering at least"
      " clustering.min_size voxels above table.min_height (%d of %zu)\n",
      kMinVisiblePixels, counted, tally.samples.size());
  std::printf(
      "  detected %d / %d = %.1f %%, type right %d / %d = %.1f %%, false positives %d,"
      " scenes without table %d\n",
      detected, counted, 100.0 * detected / std::max(counted, 1), right, detected,
      100.0 * right / std::max(detected, 1), tally.false_positives, tally.scenes_without_table);
  std::printf("\n  %-10s %8s %8s %8s %8s %8s\n", "truth", "cube", "cylinder", "cone", "unknown",
              "missed");
  for (ShapeType t : types) {
    auto& row = confusion[t];
    std::printf("  %-10s %8d %8d %8d %8d %8d\n", shapeTypeName(t), row["cube"], row["cylinder"],
                row["cone"], row["unknown"], row["missed"]);
  }
}

void printBreakdowns(const Tally& tally, const Options& options) {
  std::printf("\nMedian relative error against range, all objects (n = objects detected)\n");
  std::printf("  %-12s %5s %12s %12s\n", "range", "n", "dimensions", "volume");
  std::ofstream range_data(options.out_dir + "/error_vs_range.dat");
  range_data << "# range_centre median_dimension_error_percent median_volume_error_percent n\n";
  for (double low : {0.6, 0.9, 1.2}) {
    std::vector<const Sample*> bin;
    for (const Sample& s : tally.samples) {
      if (s.detected && s.range >= low && s.range < low + 0.3) bin.push_back(&s);
    }
    const double dims = percentile(errorsOf(bin, isDimension), 0.5);
    const double vol = percentile(errorsOf(bin, isVolume), 0.5);
    std::printf("  %.1f-%.1f m    %5zu %11.2f%% %11.2f%%\n", low, low + 0.3, bin.size(), dims, vol);
    range_data << low + 0.15 << " " << dims << " " << vol << " " << bin.size() << "\n";
  }
  std::printf("\nBoxes: median relative error against faces seen\n");
  std::printf("  %-6s %5s %12s %12s\n", "faces", "n", "edges", "volume");
  for (int faces = 1; faces <= 3; ++faces) {
    std::vector<const Sample*> bin;
    for (const Sample& s : tally.samples) {
      if (s.detected && s.found_type == ShapeType::Cube && s.faces_seen == faces) {
        bin.push_back(&s);
      }
    }
    std::printf("  %-6d %5zu %11.2f%% %11.2f%%\n", faces, bin.size(),
                percentile(errorsOf(bin, isDimension), 0.5),
                percentile(errorsOf(bin, isVolume), 0.5));
  }
  std::printf("\nOther sizes (random objects, all ranges): median relative error\n");
  for (const char* name : {"random box", "random cylinder", "random cone"}) {
    std::vector<const Sample*> bin;
    for (const Sample& s : tally.samples) {
      if (s.detected && s.name == name) bin.push_back(&s);
    }
    std::printf("  %-16s n %3zu  dimensions %6.2f%%  volume %6.2f%%\n", name, bin.size(),
                percentile(errorsOf(bin, isDimension), 0.5),
                percentile(errorsOf(bin, isVolume), 0.5));
  }
  std::vector<double> ms = tally.frame_ms;
  std::printf("\nPipeline time per VGA frame: median %.1f ms, p90 %.1f ms (%zu frames)\n",
              percentile(ms, 0.5), percentile(ms, 0.9), ms.size());
}

void writeFig12(const Tally& tally, const Options& options) {
  std::ofstream data(options.out_dir + "/fig12_volumes.dat");
  data << "# index name min_volume median_volume max_volume true_volume   [m^3], 0.6-1.2 m\n";
  int index = 1;
  for (const char* object : kPaperObjects) {
    std::vector<double> volumes;
    double truth = 0;
    for (const Sample& s : tally.samples) {
      if (s.name != object) continue;
      truth = s.volume_truth;
      if (s.detected && s.volume_estimate > 0 && s.range >= 0.6 && s.range < 1.2) {
        volumes.push_back(s.volume_estimate);
      }
    }
    if (volumes.empty()) continue;
    data << index++ << " \"" << object << "\" " << percentile(volumes, 0) << " "
         << percentile(volumes, 0.5) << " " << percentile(volumes, 1) << " " << truth << "\n";
  }
}

void writePlots(const Options& options) {
  const std::string script = options.out_dir + "/plots.gp";
  std::ofstream gp(script);
  gp << "set terminal pngcairo size 800,500 noenhanced\n"
     << "set output '" << options.out_dir << "/fig12_volumes.png'\n"
     << "set title 'Estimated volume (min / median / max, 0.6-1.2 m) beside ground truth'\n"
     << "set ylabel 'volume [m^3]'\nset xrange [0.5:4.5]\nset yrange [0:*]\nset grid ytics\n"
     << "set key top left\n"
     << "plot '" << options.out_dir << "/fig12_volumes.dat' using 1:4:3:5:xtic(2) "
     << "with yerrorbars lw 2 pt 7 title 'estimated (median, min-max)', "
     << "'' using ($1+0.15):6 with points pt 5 ps 1.5 title 'ground truth'\n"
     << "set output '" << options.out_dir << "/error_vs_range.png'\n"
     << "set title 'Median relative error against range (all rendered objects)'\n"
     << "set xlabel 'range camera - object [m]'\nset ylabel 'relative error [%]'\n"
     << "set xrange [0.6:1.5]\nset yrange [0:*]\nset xtics 0.1\n"
     << "plot '" << options.out_dir << "/error_vs_range.dat' using 1:2 with linespoints lw 2 "
     << "pt 7 title 'dimensions', '' using 1:3 with linespoints lw 2 pt 5 title 'volume'\n";
  gp.close();
  const std::string command = "gnuplot '" + script + "' 2>&1";
  if (std::system(command.c_str()) != 0) {
    std::fprintf(stderr, "benchmark_accuracy: gnuplot failed; data files are in %s\n",
                 options.out_dir.c_str());
  } else {
    std::printf("\nPlots: %s/fig12_volumes.png, %s/error_vs_range.png\n", options.out_dir.c_str(),
                options.out_dir.c_str());
  }
}

// The OSD learn set's categories (../shared/data/README.md) by scene number.
struct OsdCategory {
  const char* name;
  int first, last;
};
const OsdCategory kOsdCategories[] = {
    {"boxes", 0, 16}, {"stacked", 17, 24}, {"occluded", 25, 32}, {"cylindric", 33, 44}};

// What each object of the occluded scenes is, by label decade (2 = labels 20-29), read from the
// scenes' colour images: boxes, except a can standing upright in learn31 and cans lying on
// their side in learn30 and learn32 (round objects; the package fits upright ones only).
const std::map<int, std::map<int, ExpectedShape>> kOccludedShapes = {
    {25, {{2, ExpectedShape::Box}, {3, ExpectedShape::Box}}},
    {26, {{2, ExpectedShape::Box}, {3, ExpectedShape::Box}}},
    {27, {{2, ExpectedShape::Box}, {3, ExpectedShape::Box}}},
    {28, {{2, ExpectedShape::Box}, {3, ExpectedShape::Box}}},
    {29, {{2, ExpectedShape::Box}, {3, ExpectedShape::Box}}},
    {30, {{2, ExpectedShape::Box}, {3, ExpectedShape::Round}}},
    {31, {{2, ExpectedShape::Round}, {3, ExpectedShape::Box}}},
    {32, {{2, ExpectedShape::Box}, {3, ExpectedShape::Round}}}};

// Boxes 0-24 are boxes, cylindric 33-44 cylinders or cones, occluded 25-32 as listed above.
ExpectedShape expectedOsdShape(int scene, int decade) {
  if (scene >= 0 && scene <= 24) return ExpectedShape::Box;
  if (scene >= 33 && scene <= 44) return ExpectedShape::Round;
  const auto it = kOccludedShapes.find(scene);
  if (it == kOccludedShapes.end() || !it->second.count(decade)) return ExpectedShape::Unknown;
  return it->second.at(decade);
}

std::string countsText(const ObjectCounts& c) {
  char text[96];
  std::snprintf(text, sizeof text, "%4d / %-4d %6d %5d %5d / %-4d", c.found, c.objects, c.pieces,
                c.junk, c.type_right, c.typed);
  return text;
}

void runOsd(const Options& options) {
  std::vector<std::pair<int, fs::path>> files;  // scene number, file
  for (const auto& entry : fs::directory_iterator(options.osd_dir)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".pcd" && name.rfind("learn", 0) == 0)
      files.emplace_back(std::atoi(name.c_str() + 5), entry.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) return;
  const char* up_text = options.osd_labelled_up ? "up from the labelled table's plane"
                                                : "up estimated from the scene";
  std::printf("\nReal OSD learn scenes (%s), %s\n", options.osd_dir.c_str(), up_text);
  std::printf("  %-8s %8s %8s %8s %8s %7s  %-27s  %s\n", "scene", "table P", "table R", "object P",
              "object R", "whole", "found      pieces  junk  type", "types");
  int labelled = 0, whole = 0;
  std::map<int, LabelledObjectScore> by_category;  // index into kOsdCategories
  for (const auto& [number, file] : files) {
    pcl::PointCloud<pcl::PointXYZRGBL> cloud;
    if (pcl::io::loadPCDFile(file.string(), cloud) < 0) continue;
    pcl::PointCloud<pcl::PointXYZ> xyz;
    pcl::copyPointCloud(cloud, xyz);
    PipelineParams params = options.params;
    params.auto_up = !options.osd_labelled_up;
    Plane labelled_table;
    if (options.osd_labelled_up && labelledTablePlane(cloud, labelled_table))
      params.table.up = labelled_table.normal;
    Pipeline pipeline(params);
    const SceneResult result = pipeline.process(xyz);
    const LabelledScore score = scoreLabelledScene(cloud, result);
    const int scene = number;
    const LabelledObjectScore objects = scoreLabelledObjects(
        cloud, result.objects, [scene](int decade) { return expectedOsdShape(scene, decade); });
    for (size_t c = 0; c < std::size(kOsdCategories); ++c) {
      if (number >= kOsdCategories[c].first && number <= kOsdCategories[c].last) {
        by_category[c].whole += objects.whole;
        by_category[c].parts += objects.parts;
      }
    }
    labelled += score.labelled_objects;
    whole += score.objects_found_whole;
    std::string types;
    for (const std::string& t : score.types) types += (types.empty() ? "" : ",") + t;
    std::printf("  %-8s %7.1f%% %7.1f%% %7.1f%% %7.1f%% %3d / %-2d  %s  %s\n",
                file.stem().string().c_str(), 100 * score.table_precision, 100 * score.table_recall,
                100 * score.object_precision, 100 * score.object_recall, score.objects_found_whole,
                score.labelled_objects, countsText(objects.whole).c_str(), types.c_str());
    if (options.verbose) {
      for (const ShapeFit& fit : result.objects) {
        std::printf("      %-8s at %6.3f %6.3f %6.3f, %5d points%s%s\n",
                    shapeTypeName(fit.ok ? fit.type : ShapeType::Unknown), fit.center.x(),
                    fit.center.y(), fit.center.z(), fit.points, fit.ok ? "" : ": ",
                    fit.reason.c_str());
      }
    }
  }
  std::printf("  labelled objects (>= 500 points) found as one cluster each: %d / %d = %.1f %%\n",
              whole, labelled, 100.0 * whole / std::max(labelled, 1));

  std::printf(
      "\nReal OSD learn scenes by category (%s): found = a detection's centre in the object's\n"
      "labelled points' box + 3 cm (table frame), one object per detection; pieces = other\n"
      "detections inside an object's box, junk = the rest; type right of the found objects\n"
      "whose shape is known (boxes 0-24, cylindric 33-44, occluded as read from the images)\n\n",
      up_text);
  std::printf("  %-16s %-31s   %s\n", "", "objects (label decades)", "parts (each label)");
  std::printf("  %-16s %-31s   %s\n", "category", "found       pieces  junk  type right",
              "found       pieces  junk  type right");
  LabelledObjectScore total;
  for (size_t c = 0; c < std::size(kOsdCategories); ++c) {
    const OsdCategory& category = kOsdCategories[c];
    char name[32];
    std::snprintf(name, sizeof name, "%s %d-%d", category.name, category.first, category.last);
    std::printf("  %-16s %s   %s\n", name, countsText(by_category[c].whole).c_str(),
                countsText(by_category[c].parts).c_str());
    total.whole += by_category[c].whole;
    total.parts += by_category[c].parts;
  }
  std::printf("  %-16s %s   %s\n", "total", countsText(total.whole).c_str(),
              countsText(total.parts).c_str());
  std::printf("  objects found %.1f %%, type right %.1f %%\n",
              100.0 * total.whole.found / std::max(total.whole.objects, 1),
              100.0 * total.whole.type_right / std::max(total.whole.typed, 1));
}

// ---- everyday objects on two sensors (issue 12) ----

// Targets of issue 12 for rendered everyday objects on the RealSense, 0.4-1.2 m.
constexpr double kTargetTypeRight = 97.0, kTargetMedianError = 3.0, kTargetMaxOversize = 20.0;
constexpr double kEverydayMatchDistance = 0.1;  // [m]; objects stand >= 3 cm apart

// One row: the objects of a kind (or all) seen by a sensor, 0.4-1.2 m from it.
void printEverydayRow(const std::string& kind, const char* sensor,
                      const std::vector<const Sample*>& samples, bool with_targets) {
  int counted = 0, detected = 0, right = 0;
  std::vector<double> errors;
  double max_oversize = -100.0;
  bool any_fit = false;
  for (const Sample* s : samples) {
    if (!s->observable) continue;
    ++counted;
    if (!s->detected) continue;
    ++detected;
    right += expectedSolid(s->truth, s->fit, s->up);
    if (!s->fit.ok) continue;
    for (const Measure& m : dimensionErrors(s->truth, s->fit, s->up)) {
      errors.push_back(m.error_percent);
    }
    max_oversize = std::max(max_oversize, oversizePercent(s->truth, s->fit, s->up));
    any_fit = true;
  }
  const double right_percent = 100.0 * right / std::max(detected, 1);
  const double median = percentile(errors, 0.5);
  char oversize[16] = "-";
  if (any_fit) std::snprintf(oversize, sizeof oversize, "%ld%%", std::lround(max_oversize));
  std::printf("  %-15s %-10s %5zu %7d %8d %6d %6.1f%% %8.2f%% %8.2f%% %9s", kind.c_str(), sensor,
              samples.size(), counted, detected, right, right_percent, median,
              percentile(errors, 0.9), oversize);
  if (with_targets) {
    const bool met = right_percent >= kTargetTypeRight && median <= kTargetMedianError && any_fit &&
                     max_oversize <= kTargetMaxOversize;
    std::printf("  %s", met ? "targets met" : "targets MISSED");
  }
  std::printf("\n");
}

void printEverydayTable(const std::map<SensorModel, Tally>& tallies, const Options& options) {
  std::printf(
      "\nEveryday objects (issue 12): %d scenes per sensor, a border box and 4 others each; camera"
      " 0.5-0.7 m above the table, 40-60 deg down; objects 0.4-1.2 m away (Kinect: from 0.55 m);"
      " seed %u\n"
      "  counted: >= %d visible pixels covering clustering.min_size voxels. right: the kind's"
      " solid (bottle, cans, marker, mug: cylinder;\n  flat bottle, border box: box; bowl: cone "
      "opening up;"
      " lying can: lying cylinder or box). dim: eq. 17 on the solid's measures when right, else"
      " on its extents;\n  max over: the largest fitted extent (footprint length, width, height)"
      " over the true one, minus 1. Targets (RealSense): right >= %.0f %%, median dim <= %.0f %%,"
      " max over <= %.0f %%\n\n",
      options.everyday_scenes, options.seed, kMinVisiblePixels, kTargetTypeRight,
      kTargetMedianError, kTargetMaxOversize);
  std::printf("  %-15s %-10s %5s %7s %8s %6s %7s %9s %9s %9s\n", "kind", "sensor", "n", "counted",
              "detected", "right", "", "med dim", "p90 dim", "max over");
  for (const auto& [sensor, tally] : tallies) {
    std::vector<const Sample*> all;
    for (int k = 0; k < kEverydayKinds; ++k) {
      const std::string kind = everydayKindName(static_cast<EverydayKind>(k));
      std::vector<const Sample*> of_kind;
      for (const Sample& s : tally.samples) {
        if (s.name == kind && s.range >= 0.4 && s.range <= 1.2) of_kind.push_back(&s);
      }
      all.insert(all.end(), of_kind.begin(), of_kind.end());
      printEverydayRow(kind, sensorName(sensor), of_kind, false);
    }
    printEverydayRow("all", sensorName(sensor), all, sensor == SensorModel::RealSenseD435);
    std::printf("  (%s: false positives %d, scenes without table %d)\n\n", sensorName(sensor),
                tally.false_positives, tally.scenes_without_table);
  }
}

// Issue 15's targets for rendered clutter: objects found, type right.
constexpr double kTargetClutterFound = 95.0, kTargetClutterTypeRight = 97.0;

// One row of the clutter table. Dimension and volume errors: found objects of the right solid
// at least half visible (visible pixels >= half the pixels their rays meet, hidden or not).
void printClutterRow(const std::string& kind, int scenes, const Tally& tally) {
  int counted = 0, found = 0, right = 0, half_visible = 0;
  std::vector<double> dimensions, volumes;
  for (const Sample& s : tally.samples) {
    if (!s.observable) continue;
    ++counted;
    if (!s.detected) continue;
    ++found;
    if (!expectedSolid(s.truth, s.fit, s.up)) continue;
    ++right;
    if (2 * s.truth.visible_pixels < s.truth.unoccluded_pixels || !s.fit.ok) continue;
    ++half_visible;
    for (const Measure& m : dimensionErrors(s.truth, s.fit, s.up)) {
      dimensions.push_back(m.error_percent);
    }
    for (const Measure& m : compareToTruth(s.truth, s.fit)) {
      if (isVolume(m)) volumes.push_back(m.error_percent);
    }
  }
  const double found_percent = 100.0 * found / std::max(counted, 1);
  const double right_percent = 100.0 * right / std::max(found, 1);
  std::printf("  %-28s %6d %7d %5d %5.1f%% %6d %5d %5d %5.1f%% %9d %8.2f%% %8.2f%%  %s\n",
              kind.c_str(), scenes, counted, found, found_percent, tally.pieces,
              tally.false_positives - tally.pieces, right, right_percent, half_visible,
              percentile(dimensions, 0.5), percentile(volumes, 0.5),
              found_percent >= kTargetClutterFound && right_percent >= kTargetClutterTypeRight &&
                      percentile(dimensions, 0.5) <= 2.0 && percentile(volumes, 0.5) <= 5.0
                  ? "met"
                  : "MISSED");
}

void runClutter(const Options& options) {
  // The kinds, then the covered tables again with table.camera_height known.
  std::vector<Tally> tallies(kClutterKinds + 1);
  std::vector<uint32_t> scene_seeds = options.clutter_seeds;
  if (scene_seeds.empty()) {
    std::mt19937 seeds(options.seed);
    for (int i = 0; i < options.clutter_scenes; ++i) scene_seeds.push_back(seeds());
  }
  const int scenes = static_cast<int>(scene_seeds.size());
  auto kindOf = [](int k) {
    return k < kClutterKinds ? static_cast<ClutterKind>(k) : ClutterKind::Covered;
  };
  auto wanted = [&](int k) {
    return options.clutter_kind < 0 || static_cast<int>(kindOf(k)) == options.clutter_kind;
  };
  int total = 0, done = 0;
  for (int k = 0; k <= kClutterKinds; ++k) total += wanted(k) ? scenes : 0;
  for (int k = 0; k <= kClutterKinds; ++k) {
    if (!wanted(k)) continue;
    for (const uint32_t seed : scene_seeds) {
      runScene(clutterScene(kindOf(k), seed), options, tallies[k], 0.06, k == kClutterKinds);
      progress(++done, total);
    }
  }
  std::printf(
      "\nRendered clutter (issue 15), Kinect v1, %d scenes per kind, seed %u, up given: touching ="
      " 16 objects 2 mm apart; stacked = 6 piles\n  (box on box, box across two, can lying on a"
      " box, can on a box); half hidden = 5 boxes each hiding the lower part of an object behind;\n"
      "  covered = 24 objects 5-10 mm apart on a 0.7 x 0.5 m table. counted: >= %d visible pixels"
      " covering clustering.min_size voxels; found: matched within 6 cm;\n  pieces: other"
      " detections within an object's bounding sphere + 3 cm, junk: the rest; right: the solid"
      " expected (a lying can: lying cylinder or box);\n  dim / vol: median eq. 17 error of right"
      " solids at least half visible (n). Goal: found >= %.0f %%, right >= %.0f %%, dim <= 2 %%,"
      " vol <= 5 %%\n\n",
      scenes, options.seed, kMinVisiblePixels, kTargetClutterFound, kTargetClutterTypeRight);
  std::printf("  %-28s %6s %7s %5s %6s %6s %5s %5s %6s %9s %9s %9s  %s\n", "kind", "scenes",
              "counted", "found", "", "pieces", "junk", "right", "", "n dim/vol", "med dim",
              "med vol", "goal");
  Tally all;
  for (int k = 0; k < kClutterKinds; ++k) {
    if (!wanted(k)) continue;
    printClutterRow(clutterKindName(static_cast<ClutterKind>(k)), scenes, tallies[k]);
    all.samples.insert(all.samples.end(), tallies[k].samples.begin(), tallies[k].samples.end());
    all.false_positives += tallies[k].false_positives;
    all.pieces += tallies[k].pieces;
    all.scenes_without_table += tallies[k].scenes_without_table;
  }
  if (options.clutter_kind < 0) printClutterRow("all", scenes * kClutterKinds, all);
  if (wanted(kClutterKinds)) {
    printClutterRow("covered, camera height known", scenes, tallies[kClutterKinds]);
  }
  std::printf("  (scenes without table %d; with the camera height %d)\n", all.scenes_without_table,
              tallies[kClutterKinds].scenes_without_table);
}

void runEveryday(const Options& options) {
  std::map<SensorModel, Tally> tallies;
  const int total = options.everyday_scenes * static_cast<int>(options.sensors.size());
  int done = 0;
  for (SensorModel sensor : options.sensors) {
    std::mt19937 seeds(options.seed);  // the same scene seeds for every sensor
    for (int i = 0; i < options.everyday_scenes; ++i) {
      // A box half out of view is fitted around its visible half, up to ~9 cm from its centre.
      runScene(everydayScene(static_cast<uint32_t>(seeds()), sensor), options, tallies[sensor],
               kEverydayMatchDistance);
      progress(++done, total);
    }
  }
  printEverydayTable(tallies, options);
}

Options parse(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "benchmark_accuracy: %s needs a value\n", arg.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--paper-scenes")
      options.paper_scenes = std::stoi(value());
    else if (arg == "--random-scenes")
      options.random_scenes = std::stoi(value());
    else if (arg == "--seed")
      options.seed = static_cast<uint32_t>(std::stoul(value()));
    else if (arg == "--up")
      options.auto_up = value() == "auto";
    else if (arg == "--osd")
      options.osd_dir = value();
    else if (arg == "--osd-up") {
      const std::string up = value();
      if (up != "auto" && up != "labelled") {
        std::fprintf(stderr, "benchmark_accuracy: --osd-up takes auto or labelled\n");
        std::exit(2);
      }
      options.osd_labelled_up = up == "labelled";
    } else if (arg == "--out")
      options.out_dir = value();
    else if (arg == "--no-plots")
      options.plots = false;
    else if (arg == "--verbose")
      options.verbose = true;
    else if (arg == "--save-failures")
      options.failures_dir = value();
    else if (arg == "--set")
      setFromText(value(), options.params);
    else if (arg == "--clutter-scenes")
      options.clutter_scenes = std::stoi(value());
    else if (arg == "--clutter") {
      options.clutter_scenes = std::stoi(value());
      options.clutter_only = true;
    } else if (arg == "--clutter-kind") {
      const std::string name = value();
      for (int k = 0; k < kClutterKinds; ++k) {
        if (name == clutterKindName(static_cast<ClutterKind>(k))) options.clutter_kind = k;
      }
      if (options.clutter_kind < 0) {
        std::fprintf(stderr,
                     "benchmark_accuracy: --clutter-kind %s: touching, stacked, \"half hidden\" "
                     "or covered\n",
                     name.c_str());
        std::exit(2);
      }
    } else if (arg == "--clutter-seeds") {
      std::stringstream list(value());
      for (std::string seed; std::getline(list, seed, ',');) {
        options.clutter_seeds.push_back(static_cast<uint32_t>(std::stoul(seed)));
      }
    } else if (arg == "--everyday-scenes")
      options.everyday_scenes = std::stoi(value());
    else if (arg == "--everyday") {
      options.everyday_scenes = std::stoi(value());
      options.everyday_only = true;
    } else if (arg == "--sensor") {
      SensorModel sensor;
      const std::string name = value();
      if (!parseSensorName(name, sensor)) {
        std::fprintf(stderr, "benchmark_accuracy: --sensor %s: kinect or realsense\n",
                     name.c_str());
        std::exit(2);
      }
      options.sensors = {sensor};
    } else {
      std::fprintf(
          stderr,
          "usage: benchmark_accuracy [--paper-scenes N] [--random-scenes N] [--seed S]"
          " [--up auto] [--osd DIR] [--osd-up auto|labelled] [--out DIR] [--no-plots] [--verbose]"
          " [--save-failures DIR] [--everyday-scenes N] [--everyday N]"
          " [--sensor kinect|realsense] [--clutter-scenes N] [--clutter N]"
          " [--clutter-kind touching|stacked|\"half hidden\"|covered] [--clutter-seeds S1,S2,...]"
          " [--set stage.name=value ...]\n");
      std::exit(2);
    }
  }
  return options;
}

}  // namespace

int main(int argc, char** argv) {
  const Options options = parse(argc, argv);
  fs::create_directories(options.out_dir);
  if (!options.failures_dir.empty()) fs::create_directories(options.failures_dir);
  if (options.everyday_only) {
    runEveryday(options);
    return 0;
  }
  if (options.clutter_only) {
    runClutter(options);
    return 0;
  }
  std::mt19937 rng(options.seed);
  Tally tally;
  const int total = options.paper_scenes + options.random_scenes;
  for (int i = 0; i < total; ++i) {
    const SceneSpec spec =
        i < options.paper_scenes ? jitteredPaperScene(rng) : randomScene(rng, RandomSceneOptions());
    runScene(spec, options, tally);
    progress(i + 1, total);
  }
  std::printf(
      "Rendered Kinect-v1 scenes: %d with the paper's four objects, %d random"
      " (1-4 objects), seed %u, up %s: %zu object instances\n",
      options.paper_scenes, options.random_scenes, options.seed,
      options.auto_up ? "estimated from the scene" : "given (as from tf2)", tally.samples.size());
  printPaperTable(tally);
  printDetection(tally);
  printBreakdowns(tally, options);
  if (options.clutter_scenes > 0) runClutter(options);
  writeFig12(tally, options);
  if (options.plots) writePlots(options);
  if (!options.osd_dir.empty()) runOsd(options);
  if (options.everyday_scenes > 0) runEveryday(options);
  return 0;
}
