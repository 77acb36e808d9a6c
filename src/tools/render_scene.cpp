// Renders one Kinect-like table-top scene: PREFIX.pcd (binary, organised, optical frame) and
// PREFIX.json (ground truth). Optionally PREFIX_depth.pgm / PREFIX_rgb.ppm for a quick look.
#include "tabletop_shapes/sim/scene_renderer.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

namespace {

const char* kUsage =
    "usage: render_scene [--seed N] [--paper] [--objects K] [--noiseless] [--distance M]"
    " [--tilt DEG] [--yaw DEG] [--images] --out PREFIX";

int usageError(const std::string& what) {
  std::cerr << "render_scene: " << what << "; " << kUsage << "\n";
  return 2;
}

bool parseNumber(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return !text.empty() && end && *end == '\0' && std::isfinite(value);
}

// Depth as 16-bit PGM (millimetres) and colour as PPM; 0 / black where there is no return.
bool writeImages(const tabletop_shapes::sim::RenderedScene& scene, const std::string& prefix) {
  const auto& cloud = *scene.cloud;
  std::ofstream depth(prefix + "_depth.pgm", std::ios::binary);
  std::ofstream rgb(prefix + "_rgb.ppm", std::ios::binary);
  depth << "P5\n" << cloud.width << " " << cloud.height << "\n65535\n";
  rgb << "P6\n" << cloud.width << " " << cloud.height << "\n255\n";
  for (const auto& p : cloud.points) {
    const int mm = std::isfinite(p.z) ? static_cast<int>(std::lround(p.z * 1000.0f)) : 0;
    depth.put(static_cast<char>((mm >> 8) & 0xff)).put(static_cast<char>(mm & 0xff));
    rgb.put(static_cast<char>(p.r)).put(static_cast<char>(p.g)).put(static_cast<char>(p.b));
  }
  return static_cast<bool>(depth) && static_cast<bool>(rgb);
}

}  // namespace

int main(int argc, char** argv) {
  namespace sim = tabletop_shapes::sim;
  double seed = 1, objects = 0, distance = NAN, tilt = NAN, yaw = NAN;
  bool paper = false, noiseless = false, images = false;
  std::string prefix;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto number = [&](double& value, double lo, double hi) {
      return i + 1 < argc && parseNumber(argv[++i], value) && value >= lo && value <= hi;
    };
    if (arg == "--paper") {
      paper = true;
    } else if (arg == "--noiseless") {
      noiseless = true;
    } else if (arg == "--images") {
      images = true;
    } else if (arg == "--seed") {
      if (!number(seed, 0, 4294967295.0) || seed != std::floor(seed)) {
        return usageError("--seed needs an integer 0..2^32-1");
      }
    } else if (arg == "--objects") {
      if (!number(objects, 1, 4) || objects != std::floor(objects)) {
        return usageError("--objects needs an integer 1..4");
      }
    } else if (arg == "--distance") {
      if (!number(distance, 0.3, 5.0)) return usageError("--distance needs 0.3..5 m");
    } else if (arg == "--tilt") {
      if (!number(tilt, 0.0, 90.0)) return usageError("--tilt needs 0..90 deg");
    } else if (arg == "--yaw") {
      if (!number(yaw, -360.0, 360.0)) return usageError("--yaw needs -360..360 deg");
    } else if (arg == "--out") {
      if (i + 1 >= argc) return usageError("--out needs a prefix");
      prefix = argv[++i];
    } else {
      return usageError("unknown argument '" + arg + "'");
    }
  }
  if (prefix.empty()) return usageError("--out PREFIX is required");
  if (paper && objects > 0) return usageError("--paper and --objects exclude each other");

  const auto n_seed = static_cast<uint32_t>(seed);
  sim::SceneSpec spec;
  if (paper) {
    spec = sim::paperScene(sim::CameraPlacement{1.0f, 40.0f, 90.0f}, sim::NoiseModel{}, n_seed);
  } else {
    std::mt19937 rng(n_seed);
    sim::RandomSceneOptions options;
    if (objects > 0) options.min_objects = options.max_objects = static_cast<int>(objects);
    spec = sim::randomScene(rng, options);
  }
  if (noiseless) spec.noise = sim::NoiseModel::noiseless();
  if (!std::isnan(distance)) spec.placement.distance = static_cast<float>(distance);
  if (!std::isnan(tilt)) spec.placement.tilt_deg = static_cast<float>(tilt);
  if (!std::isnan(yaw)) spec.placement.yaw_deg = static_cast<float>(yaw);

  const auto start = std::chrono::steady_clock::now();
  const sim::RenderedScene scene = sim::renderScene(spec);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();

  if (!sim::writePcd(scene, prefix + ".pcd") ||
      !sim::writeGroundTruthJson(scene, prefix + ".json") ||
      (images && !writeImages(scene, prefix))) {
    std::cerr << "render_scene: cannot write " << prefix << ".*\n";
    return 1;
  }
  std::cout << "rendered " << scene.objects.size() << " objects in " << ms << " ms -> " << prefix
            << ".pcd, " << prefix << ".json\n";
  return 0;
}
