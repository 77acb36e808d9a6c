#include "tabletop_shapes/sim/clutter_scenes.h"

#include <algorithm>
#include <cmath>

namespace tabletop_shapes {
namespace sim {
namespace {

class Draw {
 public:
  explicit Draw(uint32_t seed) : rng_(seed) {}
  float between(float low, float high) {
    return std::uniform_real_distribution<float>(low, high)(rng_);
  }
  bool chance(float p) { return between(0.0f, 1.0f) < p; }
  std::mt19937& rng() { return rng_; }

 private:
  std::mt19937 rng_;
};

ObjectSpec box(const Eigen::Vector3f& size, const Eigen::Vector2f& at, float yaw = 0.0f,
               float base_height = 0.0f) {
  ObjectSpec object;
  object.type = ShapeType::Cube;
  object.box_size = size;
  object.height = size.z();
  object.position_on_table = at;
  object.yaw = yaw;
  object.base_height = base_height;
  object.name = base_height > 0 ? "box on others" : "box";
  return object;
}

ObjectSpec cylinder(float radius, float height, const Eigen::Vector2f& at,
                    float base_height = 0.0f) {
  ObjectSpec object;
  object.type = ShapeType::Cylinder;
  object.radius_bottom = object.radius_top = radius;
  object.height = height;
  object.position_on_table = at;
  object.base_height = base_height;
  object.name = base_height > 0 ? "can on a box" : "cylinder";
  return object;
}

// A box or an upright cylinder whose footprint fits `cell` (x, y), height in [low, high].
ObjectSpec fillCell(Draw& draw, const Eigen::Vector2f& cell, const Eigen::Vector2f& at, float low,
                    float high) {
  const float height = draw.between(low, high);
  if (draw.chance(0.35f)) return cylinder(0.5f * std::min(cell.x(), cell.y()), height, at);
  return box({cell.x(), cell.y(), height}, at);
}

// A block of `columns` x `rows` objects, cells `cell` apart with `gap` between neighbours,
// centred on the table.
void block(Draw& draw, int columns, int rows, const Eigen::Vector2f& pitch, float gap, float low,
           float high, SceneSpec& spec) {
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      const Eigen::Vector2f at(pitch.x() * (c - 0.5f * (columns - 1)),
                               pitch.y() * (r - 0.5f * (rows - 1)));
      spec.objects.push_back(fillCell(draw, pitch - Eigen::Vector2f(gap, gap), at, low, high));
    }
  }
}

// One pile at `at`: 0 box on box, 1 box across two boxes, 2 can lying on a box, 3 can on a box.
void pile(Draw& draw, int recipe, const Eigen::Vector2f& at, SceneSpec& spec) {
  const float yaw = draw.between(0.0f, static_cast<float>(kPi));
  const Eigen::Matrix2f turn = Eigen::Rotation2Df(yaw).toRotationMatrix();
  switch (recipe) {
    case 0: {
      const Eigen::Vector3f lower(draw.between(0.15f, 0.19f), draw.between(0.11f, 0.14f),
                                  draw.between(0.05f, 0.09f));
      spec.objects.push_back(box(lower, at, yaw));
      const Eigen::Vector3f upper(draw.between(0.08f, 0.12f), draw.between(0.06f, 0.09f),
                                  draw.between(0.04f, 0.07f));
      spec.objects.push_back(box(upper, at + turn * Eigen::Vector2f(0.01f, 0.0f),
                                 yaw + draw.between(-0.4f, 0.4f), lower.z()));
      return;
    }
    case 1: {
      const float height = draw.between(0.05f, 0.08f), span = draw.between(0.05f, 0.07f);
      const Eigen::Vector3f leg(0.07f, draw.between(0.07f, 0.09f), height);
      for (float side : {-1.0f, 1.0f}) {
        spec.objects.push_back(
            box(leg, at + turn * Eigen::Vector2f(side * (span + leg.x()) / 2, 0.0f), yaw));
      }
      const Eigen::Vector3f plank(span + 2 * leg.x() - 0.02f, draw.between(0.06f, 0.08f),
                                  draw.between(0.03f, 0.05f));
      spec.objects.push_back(box(plank, at, yaw, height));
      return;
    }
    case 2: {
      const Eigen::Vector3f base(draw.between(0.15f, 0.18f), draw.between(0.11f, 0.13f),
                                 draw.between(0.05f, 0.08f));
      spec.objects.push_back(box(base, at, yaw));
      ObjectSpec can =
          cylinder(draw.between(0.03f, 0.04f), draw.between(0.10f, 0.13f), at, base.z());
      can.form = ObjectForm::LyingCan;
      can.yaw = yaw;
      can.name = "can lying on a box";
      spec.objects.push_back(can);
      return;
    }
    default: {
      const Eigen::Vector3f base(draw.between(0.13f, 0.16f), draw.between(0.12f, 0.15f),
                                 draw.between(0.04f, 0.07f));
      spec.objects.push_back(box(base, at, yaw));
      spec.objects.push_back(
          cylinder(draw.between(0.03f, 0.045f), draw.between(0.08f, 0.14f), at, base.z()));
      return;
    }
  }
}

}  // namespace

const char* clutterKindName(ClutterKind kind) {
  switch (kind) {
    case ClutterKind::Touching:
      return "touching";
    case ClutterKind::Stacked:
      return "stacked";
    case ClutterKind::HalfHidden:
      return "half hidden";
    case ClutterKind::Covered:
      return "covered";
  }
  return "?";
}

SceneSpec clutterScene(ClutterKind kind, uint32_t seed) {
  Draw draw(seed);
  SceneSpec spec;
  spec.seed = seed;
  spec.table.length = 1.2f;
  spec.table.width = 0.8f;
  spec.placement.fixed_look_at = true;
  spec.placement.look_at = Eigen::Vector2f::Zero();
  spec.placement.distance = draw.between(1.0f, 1.3f);
  spec.placement.tilt_deg = draw.between(40.0f, 55.0f);
  spec.placement.yaw_deg = draw.between(0.0f, 360.0f);
  switch (kind) {
    case ClutterKind::Touching:
      block(draw, 4, 4, {0.10f, 0.09f}, 0.002f, 0.05f, 0.16f, spec);
      break;
    case ClutterKind::Stacked: {
      int recipe = static_cast<int>(draw.between(0.0f, 4.0f));
      for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 3; ++c) {
          pile(draw, recipe++ % 4, {0.27f * (c - 1), 0.27f * (r - 0.5f)}, spec);
        }
      }
      break;
    }
    case ClutterKind::HalfHidden: {
      spec.placement.yaw_deg = draw.between(80.0f, 100.0f);  // looking along +y, across the rows
      spec.placement.tilt_deg = draw.between(30.0f, 40.0f);
      for (int c = 0; c < 5; ++c) {
        const float x = 0.16f * (c - 2);
        const float front_height = draw.between(0.12f, 0.15f);
        spec.objects.push_back(box({0.09f, 0.05f, front_height}, {x, -0.06f}));
        // Behind it, 3-5 cm back, shifted sideways by up to 4 cm; its top shows above the front
        // box, its lower part is hidden.
        const Eigen::Vector2f behind(x + draw.between(-0.04f, 0.04f),
                                     -0.035f + draw.between(0.03f, 0.05f) + 0.04f);
        spec.objects.push_back(draw.chance(0.5f)
                                   ? box({0.10f, 0.08f, draw.between(0.12f, 0.18f)}, behind)
                                   : cylinder(0.04f, draw.between(0.12f, 0.18f), behind));
      }
      break;
    }
    case ClutterKind::Covered:
      spec.table.length = 0.7f;
      spec.table.width = 0.5f;
      block(draw, 6, 4, {0.105f, 0.11f}, draw.between(0.005f, 0.01f), 0.05f, 0.15f, spec);
      break;
  }
  return spec;
}

}  // namespace sim
}  // namespace tabletop_shapes
