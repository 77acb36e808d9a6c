// Rendered clutter with ground truth (issue 15): crowded tables where objects touch, lie on or
// across others, hide each other, and cover most of the table. Each kind is a fixed recipe with
// random sizes, yaws and camera drawn from the seed, so a seed always gives the same scene.
#pragma once

#include "tabletop_shapes/sim/scene_renderer.h"

namespace tabletop_shapes {
namespace sim {

enum class ClutterKind {
  Touching,    // 16 boxes and cylinders in a 4 x 4 block, neighbours 2 mm apart
  Stacked,     // 6 piles: box on box, box across two boxes, can lying on a box, can on a box
  HalfHidden,  // 5 boxes in front, each hiding the lower part of an object 3-5 cm behind it
  Covered,     // 24 boxes and cylinders 5-10 mm apart covering ~70 % of a 0.7 x 0.5 m table
};
constexpr int kClutterKinds = 4;
const char* clutterKindName(ClutterKind kind);  // "touching", "stacked", "half hidden", "covered"

// A Kinect v1 scene of `kind`; the camera 1.0-1.3 m from the table centre, 40-55 deg down, any
// yaw (HalfHidden: looking across the rows, 30-40 deg down, yaw 80-100 deg).
SceneSpec clutterScene(ClutterKind kind, uint32_t seed);

}  // namespace sim
}  // namespace tabletop_shapes
