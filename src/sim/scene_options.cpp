#include "tabletop_shapes/sim/scene_options.h"

#include <cstdlib>
#include <random>

namespace tabletop_shapes {
namespace sim {

bool parseNumber(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return !text.empty() && end && *end == '\0' && std::isfinite(value);
}

OptionRead readSceneOption(int argc, char** argv, int& i, SceneChoice& choice, std::string& error) {
  const std::string arg = argv[i];
  double value = 0.0;
  auto number = [&](double lo, double hi, bool integer, const char* needs) {
    if (i + 1 < argc && parseNumber(argv[++i], value) && value >= lo && value <= hi &&
        (!integer || value == std::floor(value))) {
      return true;
    }
    error = arg + " needs " + needs;
    return false;
  };
  if (arg == "--paper") {
    choice.paper = true;
  } else if (arg == "--everyday") {
    choice.everyday = true;
  } else if (arg == "--sensor") {
    if (i + 1 >= argc || !parseSensorName(argv[++i], choice.sensor)) {
      error = arg + " needs kinect or realsense";
      return OptionRead::Invalid;
    }
  } else if (arg == "--noiseless") {
    choice.noiseless = true;
  } else if (arg == "--seed") {
    if (!number(0, 4294967295.0, true, "an integer 0..2^32-1")) return OptionRead::Invalid;
    choice.seed = static_cast<uint32_t>(value);
  } else if (arg == "--objects") {
    if (!number(1, 4, true, "an integer 1..4")) return OptionRead::Invalid;
    choice.objects = static_cast<int>(value);
  } else if (arg == "--distance") {
    if (!number(0.3, 5.0, false, "0.3..5 m")) return OptionRead::Invalid;
    choice.distance = static_cast<float>(value);
  } else if (arg == "--tilt") {
    if (!number(0.0, 90.0, false, "0..90 deg")) return OptionRead::Invalid;
    choice.tilt_deg = static_cast<float>(value);
  } else if (arg == "--yaw") {
    if (!number(-360.0, 360.0, false, "-360..360 deg")) return OptionRead::Invalid;
    choice.yaw_deg = static_cast<float>(value);
  } else {
    return OptionRead::NotASceneOption;
  }
  return OptionRead::Read;
}

std::string sceneChoiceError(const SceneChoice& choice) {
  if (choice.paper + choice.everyday + (choice.objects > 0) > 1) {
    return "--paper, --everyday and --objects exclude each other";
  }
  return "";
}

SceneSpec sceneSpecFrom(const SceneChoice& choice) {
  SceneSpec spec;
  if (choice.everyday) {
    spec = everydayScene(choice.seed, choice.sensor);
  } else if (choice.paper) {
    spec = paperScene(CameraPlacement{1.0f, 40.0f, 90.0f}, NoiseModel{}, choice.seed);
  } else {
    std::mt19937 rng(choice.seed);
    RandomSceneOptions options;
    if (choice.objects > 0) options.min_objects = options.max_objects = choice.objects;
    spec = randomScene(rng, options);
  }
  if (!choice.everyday) setSensor(spec, choice.sensor);
  if (choice.noiseless) spec.noise = NoiseModel::noiseless();
  if (!std::isnan(choice.distance)) spec.placement.distance = choice.distance;
  if (!std::isnan(choice.tilt_deg)) spec.placement.tilt_deg = choice.tilt_deg;
  if (!std::isnan(choice.yaw_deg)) spec.placement.yaw_deg = choice.yaw_deg;
  return spec;
}

}  // namespace sim
}  // namespace tabletop_shapes
