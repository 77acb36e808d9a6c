// Renders Kinect-like table scenes into an OpenNI2 recording (.oni) that the OpenNI2 driver
// nodelet plays like a camera (`camera.launch device_id:=FILE.oni`). Prints the recording's path
// on stdout (and nothing else), so a launch file can generate one at launch time:
//   <param name="x" command="rosrun tabletop_shapes render_oni --out /tmp/scene.oni"/>
// The file is written under a temporary name and renamed, so readers never see half a file
// (unless --truncate asks for one, to test how a player copes with a damaged recording).
#include "tabletop_shapes/sim/oni_writer.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

const char* kUsage =
    "usage: render_oni [--paper | --objects K] [--seed N] [--frames N] [--repeat] [--qvga]"
    " [--noiseless] [--no-color] [--distance M] [--tilt DEG] [--yaw DEG] [--fps N]"
    " [--truncate BYTES] [--json] --out FILE.oni";

int usageError(const std::string& what) {
  std::cerr << "render_oni: " << what << "; " << kUsage << "\n";
  return 2;
}

bool parseNumber(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return !text.empty() && end && *end == '\0' && std::isfinite(value);
}

}  // namespace

int main(int argc, char** argv) {
  namespace sim = tabletop_shapes::sim;
  double seed = 1, objects = 0, frames = 1, fps = 30, truncate = -1;
  double distance = NAN, tilt = NAN, yaw = NAN;
  bool paper = false, noiseless = false, repeat = false, qvga = false, color = true, json = false;
  std::string path;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto number = [&](double& value, double lo, double hi, bool integer) {
      return i + 1 < argc && parseNumber(argv[++i], value) && value >= lo && value <= hi &&
             (!integer || value == std::floor(value));
    };
    if (arg == "--paper") {
      paper = true;
    } else if (arg == "--noiseless") {
      noiseless = true;
    } else if (arg == "--repeat") {
      repeat = true;
    } else if (arg == "--qvga") {
      qvga = true;
    } else if (arg == "--no-color") {
      color = false;
    } else if (arg == "--json") {
      json = true;
    } else if (arg == "--seed") {
      if (!number(seed, 0, 4294967295.0, true)) return usageError("--seed needs 0..2^32-1");
    } else if (arg == "--objects") {
      if (!number(objects, 1, 4, true)) return usageError("--objects needs 1..4");
    } else if (arg == "--frames") {
      if (!number(frames, 1, 1000, true)) return usageError("--frames needs 1..1000");
    } else if (arg == "--fps") {
      if (!number(fps, 1, 120, true)) return usageError("--fps needs 1..120");
    } else if (arg == "--truncate") {
      if (!number(truncate, 0, 1e12, true)) return usageError("--truncate needs a byte count");
    } else if (arg == "--distance") {
      if (!number(distance, 0.3, 5.0, false)) return usageError("--distance needs 0.3..5 m");
    } else if (arg == "--tilt") {
      if (!number(tilt, 0.0, 90.0, false)) return usageError("--tilt needs 0..90 deg");
    } else if (arg == "--yaw") {
      if (!number(yaw, -360.0, 360.0, false)) return usageError("--yaw needs -360..360 deg");
    } else if (arg == "--out") {
      if (i + 1 >= argc) return usageError("--out needs a file name");
      path = argv[++i];
    } else {
      return usageError("unknown argument '" + arg + "'");
    }
  }
  if (path.empty()) return usageError("--out FILE.oni is required");
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
  if (qvga) {  // the same field of view at half the resolution
    sim::CameraIntrinsics& camera = spec.camera;
    camera.width /= 2;
    camera.height /= 2;
    camera.fx /= 2.0f;
    camera.fy /= 2.0f;
    camera.cx = (camera.width - 1) / 2.0f;
    camera.cy = (camera.height - 1) / 2.0f;
  }

  sim::OniRecordingOptions options;
  options.width = spec.camera.width;
  options.height = spec.camera.height;
  options.fps = static_cast<int>(fps);
  options.horizontal_fov = sim::fieldOfView(spec.camera.width, spec.camera.fx);
  options.vertical_fov = sim::fieldOfView(spec.camera.height, spec.camera.fy);
  options.with_color = color;

  const std::string temporary = path + ".tmp" + std::to_string(getpid());
  sim::OniWriter writer;
  if (!writer.open(temporary, options)) {
    std::cerr << "render_oni: " << writer.error() << "\n";
    return 1;
  }
  sim::RgbdFrame frame;
  for (int i = 0; i < static_cast<int>(frames); ++i) {
    if (i == 0 || !repeat) {  // a new noise draw per frame, like a static real camera
      sim::SceneSpec frame_spec = spec;
      frame_spec.seed = spec.seed + static_cast<uint32_t>(i);
      const sim::RenderedScene scene = sim::renderScene(frame_spec);
      frame = sim::rgbdFrameFromCloud(*scene.cloud);
      if (!color) frame.rgb.clear();
      if (i == 0 && json && !sim::writeGroundTruthJson(scene, path + ".json")) {
        std::cerr << "render_oni: cannot write " << path << ".json\n";
        return 1;
      }
    }
    if (!writer.addFrame(frame)) {
      std::cerr << "render_oni: " << writer.error() << "\n";
      return 1;
    }
  }
  if (!writer.close()) {
    std::cerr << "render_oni: " << writer.error() << "\n";
    return 1;
  }
  std::error_code error;
  if (truncate >= 0) {
    std::filesystem::resize_file(temporary, static_cast<uintmax_t>(truncate), error);
  }
  if (!error) std::filesystem::rename(temporary, path, error);
  if (error) {
    std::cerr << "render_oni: " << path << ": " << error.message() << "\n";
    std::filesystem::remove(temporary, error);
    return 1;
  }
  std::cerr << "render_oni: " << writer.frameCount() << " frames " << options.width << "x"
            << options.height << " @ " << options.fps << " Hz -> " << path << "\n";
  std::cout << path << std::flush;
  return 0;
}
