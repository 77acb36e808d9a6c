// §3.1 model prediction from the variation of normals (eq. 1).
#pragma once

#include "tabletop_shapes/core/normals.h"

namespace tabletop_shapes {

struct Prediction {
  ShapeType guess = ShapeType::Unknown;  // Cube or Cylinder (a cone is round: Cylinder)
  float score = 0.0f;                    // mean of the middle section of sorted d(p)
};

Prediction predictShape(const NormalCloud& object, const PredictorParams& params);

}  // namespace tabletop_shapes
