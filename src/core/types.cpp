#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

const char* shapeTypeName(ShapeType type) {
  switch (type) {
    case ShapeType::Cube:
      return "cube";
    case ShapeType::Cylinder:
      return "cylinder";
    case ShapeType::Cone:
      return "cone";
    case ShapeType::Unknown:
      break;
  }
  return "unknown";
}

}  // namespace tabletop_shapes
