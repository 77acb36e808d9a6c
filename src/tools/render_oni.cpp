// Renders Kinect-like table scenes into an OpenNI2 recording (.oni) that the OpenNI2 driver
// nodelet plays like a camera (`camera.launch device_id:=FILE.oni`). Prints the recording's path
// on stdout (and nothing else), so a launch file can generate one at launch time:
//   <param name="x" command="rosrun tabletop_shapes render_oni --out /tmp/scene.oni"/>
// The file is written under a temporary name and renamed, so readers never see half a file
// (unless --truncate asks for one, to test how a player copes with a damaged recording).
#include "tabletop_shapes/sim/oni_writer.h"
#include "tabletop_shapes/sim/scene_options.h"
#include "tabletop_shapes/sim/scene_renderer.h"
#include "tabletop_shapes/sim/speed_scenes.h"

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
    "usage: render_oni [--paper | --objects K | --everyday | --speed-scene K]"
    " [--sensor kinect|realsense]"
    " [--seed N] [--frames N] [--repeat] [--qvga]"
    " [--noiseless] [--no-color] [--distance M] [--tilt DEG] [--yaw DEG] [--fps N]"
    " [--truncate BYTES] [--json] --out FILE.oni";

int usageError(const std::string& what) {
  std::cerr << "render_oni: " << what << "; " << kUsage << "\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  namespace sim = tabletop_shapes::sim;
  sim::SceneChoice choice;
  double frames = 1, fps = 30, truncate = -1;
  double speed_objects = 0;  // --speed-scene: make benchmark-speed's grid of K objects
  bool repeat = false, qvga = false, color = true, json = false;
  std::string path, usage_error;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const sim::OptionRead read = sim::readSceneOption(argc, argv, i, choice, usage_error);
    if (read == sim::OptionRead::Invalid) return usageError(usage_error);
    if (read == sim::OptionRead::Read) continue;
    auto number = [&](double& value, double lo, double hi) {
      return i + 1 < argc && sim::parseNumber(argv[++i], value) && value >= lo && value <= hi &&
             value == std::floor(value);
    };
    if (arg == "--speed-scene") {
      if (!number(speed_objects, 1, 32)) return usageError("--speed-scene needs 1..32 objects");
    } else if (arg == "--repeat") {
      repeat = true;
    } else if (arg == "--qvga") {
      qvga = true;
    } else if (arg == "--no-color") {
      color = false;
    } else if (arg == "--json") {
      json = true;
    } else if (arg == "--frames") {
      if (!number(frames, 1, 1000)) return usageError("--frames needs 1..1000");
    } else if (arg == "--fps") {
      if (!number(fps, 1, 120)) return usageError("--fps needs 1..120");
    } else if (arg == "--truncate") {
      if (!number(truncate, 0, 1e12)) return usageError("--truncate needs a byte count");
    } else if (arg == "--out") {
      if (i + 1 >= argc) return usageError("--out needs a file name");
      path = argv[++i];
    } else {
      return usageError("unknown argument '" + arg + "'");
    }
  }
  if (path.empty()) return usageError("--out FILE.oni is required");
  usage_error = sim::sceneChoiceError(choice);
  if (speed_objects > 0 && (choice.paper || choice.everyday || choice.objects > 0)) {
    usage_error = "--speed-scene excludes --paper, --everyday and --objects";
  }
  if (!usage_error.empty()) return usageError(usage_error);
  // The speed scene is the one speed_feed publishes as PointCloud2, so that both feeds of the
  // benchmark show the same frames (noise seeds 1, 2, ... as speed_feed's renders).
  sim::SceneSpec spec = speed_objects > 0
                            ? sim::speedScene(static_cast<int>(speed_objects), 640, 480, 1)
                            : sim::sceneSpecFrom(choice);
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
