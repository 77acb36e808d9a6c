#include "tabletop_shapes/sim/speed_scenes.h"

#include <algorithm>
#include <cmath>

namespace tabletop_shapes {
namespace sim {
namespace {

// Small enough that 32 fit on the table in 13.5 cm cells: 2.7-5 cm gaps, over the clustering's 2 cm
// tolerance, so each is one cluster.
ObjectSpec gridObject(int index) {
  ObjectSpec object;
  switch (index % 4) {
    case 0:
      object.type = ShapeType::Cube;
      object.box_size = {0.09f, 0.06f, 0.10f};
      break;
    case 1:
      object.type = ShapeType::Cylinder;
      object.radius_bottom = object.radius_top = 0.04f;
      object.height = 0.12f;
      break;
    case 2:
      object.type = ShapeType::Cone;
      object.radius_bottom = 0.035f;
      object.radius_top = 0.045f;
      object.height = 0.11f;
      break;
    default:
      object.type = ShapeType::Cube;
      object.box_size = {0.08f, 0.07f, 0.06f};
      break;
  }
  object.height = object.type == ShapeType::Cube ? object.box_size.z() : object.height;
  object.yaw = 0.35f * static_cast<float>(index);
  return object;
}

}  // namespace

SceneSpec speedScene(int objects, int width, int height, uint32_t seed) {
  constexpr float kCell = 0.135f;
  constexpr int kColumns = 8;
  SceneSpec spec;
  spec.seed = seed;
  spec.table.length = 1.4f;
  spec.table.width = 1.0f;
  spec.placement = CameraPlacement{1.4f, 45.0f, 90.0f};
  // The Kinect's field of view at any resolution: focal length and centre scale with the width.
  const float scale = static_cast<float>(width) / 640.0f;
  spec.camera.width = width;
  spec.camera.height = height;
  spec.camera.fx = spec.camera.fy = 575.8f * scale;
  spec.camera.cx = 0.5f * static_cast<float>(width) - 0.5f;
  spec.camera.cy = 0.5f * static_cast<float>(height) - 0.5f;
  const int count = std::clamp(objects, 0, 32);
  const int columns = std::min(count, kColumns);
  const int rows = (count + kColumns - 1) / kColumns;
  for (int i = 0; i < count; ++i) {
    ObjectSpec object = gridObject(i);
    const int column = i % kColumns, row = i / kColumns;
    object.position_on_table = {kCell * (static_cast<float>(column) - 0.5f * (columns - 1)),
                                kCell * (static_cast<float>(row) - 0.5f * (rows - 1))};
    spec.objects.push_back(object);
  }
  return spec;
}

}  // namespace sim
}  // namespace tabletop_shapes
