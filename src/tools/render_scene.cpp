// Renders one Kinect-like (or RealSense-like) table-top scene: PREFIX.pcd (binary, organised,
// optical frame) and PREFIX.json (ground truth). Optionally PREFIX_depth.pgm / PREFIX_rgb.ppm for a
// quick look.
#include "tabletop_shapes/sim/scene_options.h"
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
    "usage: render_scene [--seed N] [--paper | --objects K | --everyday]"
    " [--sensor kinect|realsense] [--noiseless] [--distance M] [--tilt DEG] [--yaw DEG]"
    " [--images] --out PREFIX";

int usageError(const std::string& what) {
  std::cerr << "render_scene: " << what << "; " << kUsage << "\n";
  return 2;
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
  sim::SceneChoice choice;
  bool images = false;
  std::string prefix, error;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const sim::OptionRead read = sim::readSceneOption(argc, argv, i, choice, error);
    if (read == sim::OptionRead::Invalid) return usageError(error);
    if (read == sim::OptionRead::Read) continue;
    if (arg == "--images") {
      images = true;
    } else if (arg == "--out") {
      if (i + 1 >= argc) return usageError("--out needs a prefix");
      prefix = argv[++i];
    } else {
      return usageError("unknown argument '" + arg + "'");
    }
  }
  if (prefix.empty()) return usageError("--out PREFIX is required");
  error = sim::sceneChoiceError(choice);
  if (!error.empty()) return usageError(error);
  const sim::SceneSpec spec = sim::sceneSpecFrom(choice);

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
