// The scene a rendering tool draws, chosen on its command line: shared by render_scene and
// render_oni, so that both read --paper, --objects, --everyday, --sensor, --seed, --noiseless,
// --distance, --tilt and --yaw the same way.
#pragma once

#include "tabletop_shapes/sim/scene_renderer.h"

#include <cmath>
#include <string>

namespace tabletop_shapes {
namespace sim {

struct SceneChoice {
  bool paper = false;     // the paper's four objects, camera at 1 m, 40 deg down, yaw 90 deg
  bool everyday = false;  // everydayScene(seed, sensor)
  SensorModel sensor = SensorModel::KinectV1;
  bool noiseless = false;
  uint32_t seed = 1;
  int objects = 0;  // random scene with this many objects; 0: 1-4 at random
  float distance = NAN, tilt_deg = NAN, yaw_deg = NAN;  // NAN: the scene's own
};

enum class OptionRead { NotASceneOption, Read, Invalid };

// Reads argv[i] (and its value, advancing i) into `choice` when it is a scene option; on
// Invalid, `error` says what the option needs.
OptionRead readSceneOption(int argc, char** argv, int& i, SceneChoice& choice, std::string& error);

// Empty when the options go together, else why not.
std::string sceneChoiceError(const SceneChoice& choice);

SceneSpec sceneSpecFrom(const SceneChoice& choice);

// A finite number that is all of `text` (strtod).
bool parseNumber(const std::string& text, double& value);

}  // namespace sim
}  // namespace tabletop_shapes
