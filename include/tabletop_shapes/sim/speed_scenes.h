// Scenes of the speed benchmark: a grid of N small objects (boxes, cylinders, truncated cones
// in turn) standing a few centimetres apart on a table, seen from a fixed camera at any of the
// benchmark's resolutions. Fixed layouts, so that the time of a scene depends only on its
// object count and resolution, and the same scene can be rendered by the core-only benchmark
// and by the ROS publisher of the chain benchmark.
#pragma once

#include "tabletop_shapes/sim/scene_renderer.h"

namespace tabletop_shapes {
namespace sim {

// `objects` (1..32) on the table, the camera 1.4 m from their centre, 45 deg below level,
// `width` x `height` pixels with the Kinect's field of view; `seed` draws the sensor noise.
SceneSpec speedScene(int objects, int width = 640, int height = 480, uint32_t seed = 1);

}  // namespace sim
}  // namespace tabletop_shapes
