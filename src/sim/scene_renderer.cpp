#include "tabletop_shapes/sim/scene_renderer.h"

#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <numeric>
#include <sstream>

namespace tabletop_shapes {
namespace sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMinT = 1e-6;  // ignore hits at the ray origin

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Rgb = std::array<float, 3>;

struct Hit {
  double t = kInf;             // along the ray d = (x, y, 1) in the optical frame, so t = depth z
  Vec3 normal = Vec3::Zero();  // world, facing the ray
  int label = kNoReturn;
};

// A solid in the world: an oriented box (centre origin) or an upright truncated cone / cylinder
// (origin at the bottom centre, local z up). Intersections are computed in the local frame.
struct Solid {
  enum Kind { kBox, kRound } kind = kBox;
  Mat3 world_from_local = Mat3::Identity();
  Vec3 origin = Vec3::Zero();
  Vec3 half_size = Vec3::Zero();                         // box
  double radius_bottom = 0, radius_top = 0, height = 0;  // round
  // Round: which caps are there (a bowl's or a mug's top is open); the top cap may be a ring
  // (a rim) with this inner radius.
  bool bottom_cap = true, top_cap = true;
  double top_cap_inner_radius = 0;
  int label = kNoReturn;
  Rgb colour{0, 0, 0};

  void intersect(const Vec3& ray_origin, const Vec3& ray_dir, Hit& hit) const {
    const Vec3 o = world_from_local.transpose() * (ray_origin - origin);
    const Vec3 d = world_from_local.transpose() * ray_dir;
    Vec3 local_normal;
    const double t =
        kind == kBox ? intersectBox(o, d, local_normal) : intersectRound(o, d, local_normal);
    if (t < hit.t) {
      hit.t = t;
      hit.normal = world_from_local * local_normal;
      hit.label = label;
    }
  }

  // Slab test; the entry face gives the normal. A ray starting inside is a miss.
  double intersectBox(const Vec3& o, const Vec3& d, Vec3& normal) const {
    double t_near = -kInf, t_far = kInf;
    for (int i = 0; i < 3; ++i) {
      if (std::abs(d[i]) < 1e-15) {
        if (std::abs(o[i]) > half_size[i]) return kInf;
        continue;
      }
      const double t1 = (-half_size[i] - o[i]) / d[i];
      const double t2 = (half_size[i] - o[i]) / d[i];
      const double entry = std::min(t1, t2);
      if (entry > t_near) {
        t_near = entry;
        normal = Vec3::Zero();
        normal[i] = d[i] > 0 ? -1.0 : 1.0;
      }
      t_far = std::min(t_far, std::max(t1, t2));
    }
    if (t_near > t_far || t_near < kMinT) return kInf;
    return t_near;
  }

  // Side: x^2 + y^2 = (rb + s z)^2 for 0 <= z <= h (rb + s z > 0 there, so only the right
  // nappe); caps: discs at z = 0 (rb) and z = h (rt).
  double intersectRound(const Vec3& o, const Vec3& d, Vec3& normal) const {
    double best = kInf;
    const double slope = (radius_top - radius_bottom) / height;
    const double k = radius_bottom + slope * o.z();
    const double a = d.x() * d.x() + d.y() * d.y() - slope * slope * d.z() * d.z();
    const double b = 2.0 * (o.x() * d.x() + o.y() * d.y() - slope * k * d.z());
    const double c = o.x() * o.x() + o.y() * o.y() - k * k;
    double roots[2] = {kInf, kInf};
    if (std::abs(a) > 1e-15) {
      const double disc = b * b - 4 * a * c;
      if (disc >= 0) {
        // Numerically stable pair of roots.
        const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
        roots[0] = q / a;
        roots[1] = q != 0 ? c / q : kInf;
      }
    } else if (std::abs(b) > 1e-15) {
      roots[0] = -c / b;
    }
    for (double t : roots) {
      if (!(t > kMinT) || t >= best) continue;
      const Vec3 p = o + t * d;
      if (p.z() < 0 || p.z() > height) continue;
      best = t;
      normal = Vec3(p.x(), p.y(), -slope * (radius_bottom + slope * p.z())).normalized();
    }
    if (std::abs(d.z()) > 1e-15) {
      const double no_cap = -1.0;  // radius of a missing cap: skipped
      for (const auto& [z, r, r_inner, nz] :
           {std::array<double, 4>{height, top_cap ? radius_top : no_cap, top_cap_inner_radius, 1.0},
            std::array<double, 4>{0.0, bottom_cap ? radius_bottom : no_cap, 0.0, -1.0}}) {
        const double t = (z - o.z()) / d.z();
        if (r < 0 || !(t > kMinT) || t >= best) continue;
        const Vec3 p = o + t * d;
        const double r2 = p.x() * p.x() + p.y() * p.y();
        if (r2 > r * r || r2 < r_inner * r_inner) continue;
        best = t;
        normal = Vec3(0, 0, nz);
      }
    }
    return best;
  }
};

// Pixel rectangle [u0, u1] x [v0, v1] that contains the solid's image (the whole image when
// the solid reaches behind the camera), widened by `margin_px` for jittered rays.
struct PixelRect {
  int u0, v0, u1, v1;
  bool contains(int u, int v) const { return u >= u0 && u <= u1 && v >= v0 && v <= v1; }
};

PixelRect projectedRect(const Solid& solid, const Eigen::Isometry3d& camera_from_world,
                        const CameraIntrinsics& cam, double margin_px) {
  const PixelRect whole{0, 0, cam.width - 1, cam.height - 1};
  Vec3 lo, hi;  // local bounding box
  if (solid.kind == Solid::kBox) {
    lo = -solid.half_size;
    hi = solid.half_size;
  } else {
    const double r = std::max(solid.radius_bottom, solid.radius_top);
    lo = Vec3(-r, -r, 0);
    hi = Vec3(r, r, solid.height);
  }
  double u_min = kInf, v_min = kInf, u_max = -kInf, v_max = -kInf;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 local((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                     (corner & 4) ? hi.z() : lo.z());
    const Vec3 p = camera_from_world * (solid.origin + solid.world_from_local * local);
    if (p.z() < 1e-3) return whole;
    const double u = cam.fx * p.x() / p.z() + cam.cx, v = cam.fy * p.y() / p.z() + cam.cy;
    u_min = std::min(u_min, u);
    u_max = std::max(u_max, u);
    v_min = std::min(v_min, v);
    v_max = std::max(v_max, v);
  }
  auto clampPixel = [](double x, int limit) {
    return static_cast<int>(std::clamp(x, -1.0, static_cast<double>(limit)));
  };
  return {clampPixel(std::floor(u_min - margin_px), cam.width),
          clampPixel(std::floor(v_min - margin_px), cam.height),
          clampPixel(std::ceil(u_max + margin_px), cam.width),
          clampPixel(std::ceil(v_max + margin_px), cam.height)};
}

Solid makeBox(const Vec3& centre, const Vec3& size, double yaw, int label, const Rgb& colour) {
  Solid s;
  s.kind = Solid::kBox;
  s.world_from_local = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
  s.origin = centre;
  s.half_size = size / 2;
  s.label = label;
  s.colour = colour;
  return s;
}

// Upright truncated cone in the object's frame: `bottom` is the world position of its bottom
// centre, `rotation` world_from_local.
Solid makeRound(const Vec3& bottom, const Mat3& rotation, double radius_bottom, double radius_top,
                double height, int label, const Rgb& colour) {
  Solid s;
  s.kind = Solid::kRound;
  s.world_from_local = rotation;
  s.origin = bottom;
  s.radius_bottom = radius_bottom;
  s.radius_top = radius_top;
  s.height = height;
  s.label = label;
  s.colour = colour;
  return s;
}

// Mug handle: a C of three bars on the local +x side, from 25 % to 80 % of the height [m].
constexpr double kHandleReach = 0.025, kHandleBar = 0.008, kHandleWidth = 0.012;

// The solids that make up one object (several for the everyday forms, all with its label).
void addObjectSolids(const ObjectSpec& object, const Vec3& bottom, int label, const Rgb& colour,
                     std::vector<Solid>& solids) {
  const Mat3 yaw = Eigen::AngleAxisd(object.yaw, Vec3::UnitZ()).toRotationMatrix();
  const double rb = object.radius_bottom, h = object.height;
  const double rt = object.type == ShapeType::Cylinder ? rb : object.radius_top;
  auto round = [&](double z0, double r0, double r1, double height) {
    solids.push_back(makeRound(bottom + Vec3(0, 0, z0), yaw, r0, r1, height, label, colour));
    return &solids.back();
  };
  auto box = [&](const Vec3& local_centre, const Vec3& size) {
    solids.push_back(makeBox(bottom + yaw * local_centre, size, object.yaw, label, colour));
  };
  switch (object.form) {
    case ObjectForm::Plain:
      if (object.type == ShapeType::Cube) {
        const Vec3 size = object.box_size.cast<double>();
        box(Vec3(0, 0, size.z() / 2), size);
      } else if (h > 0 && rb > 0 && rt > 0) {
        round(0, rb, rt, h);
      }
      return;
    case ObjectForm::Bottle: {
      // Body 60 %, shoulder 17 %, neck 16 %, cap 7 % of the height.
      const double neck = std::max(0.35 * rb, 0.011);
      round(0, rb, rb, 0.60 * h);
      round(0.60 * h, rb, neck, 0.17 * h);
      round(0.77 * h, neck, neck, 0.16 * h);
      round(0.93 * h, neck + 0.0015, neck + 0.0015, 0.07 * h);
      return;
    }
    case ObjectForm::FlatBottle: {
      // Body with vertical edges rounded to a quarter of its thickness; a round cap on top.
      const Vec3 size = object.box_size.cast<double>();
      const double corner = 0.25 * std::min(size.x(), size.y());
      const double cap_radius = std::min(0.014, size.y() / 2 - 0.005), cap_height = 0.02;
      const double body = size.z() - cap_height;
      box(Vec3(0, 0, body / 2), Vec3(size.x() - 2 * corner, size.y(), body));
      box(Vec3(0, 0, body / 2), Vec3(size.x(), size.y() - 2 * corner, body));
      for (const double sx : {-1.0, 1.0}) {
        for (const double sy : {-1.0, 1.0}) {
          const Vec3 offset(sx * (size.x() / 2 - corner), sy * (size.y() / 2 - corner), 0);
          solids.push_back(
              makeRound(bottom + yaw * offset, yaw, corner, corner, body, label, colour));
        }
      }
      round(body, cap_radius, cap_radius, cap_height);
      return;
    }
    case ObjectForm::Bowl:
    case ObjectForm::Mug: {
      // Open shell: outer wall with a bottom and a rim ring, inner wall with the inner floor.
      const double wall = object.wall_thickness;
      Solid* outer = round(0, rb, rt, h);
      outer->top_cap_inner_radius = rt - wall;
      round(wall, rb - wall, rt - wall, h - wall)->top_cap = false;
      if (object.form == ObjectForm::Mug) {
        const double r = rb, arm = r + kHandleReach / 2 - wall / 2;
        box(Vec3(arm, 0, 0.8 * h), Vec3(kHandleReach + wall, kHandleWidth, kHandleBar));
        box(Vec3(arm, 0, 0.25 * h), Vec3(kHandleReach + wall, kHandleWidth, kHandleBar));
        box(Vec3(r + kHandleReach - kHandleBar / 2, 0, 0.525 * h),
            Vec3(kHandleBar, kHandleWidth, 0.55 * h + kHandleBar));
      }
      return;
    }
    case ObjectForm::LyingCan: {
      // Local z (the can's axis) along the object's x; bottom centre at one end.
      const Mat3 lying = yaw * Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()).toRotationMatrix();
      solids.push_back(makeRound(bottom + Vec3(0, 0, rb) - lying * Vec3(0, 0, h / 2), lying, rb, rb,
                                 h, label, colour));
      return;
    }
  }
}

// Distinct, saturated object colours; surfaces of the room are muted.
const Rgb kObjectPalette[] = {{220, 40, 40},  {40, 170, 60},  {40, 90, 220},  {230, 200, 30},
                              {200, 50, 200}, {30, 190, 200}, {240, 130, 20}, {120, 60, 180}};
const Rgb kTableColour{170, 120, 70};
const Rgb kFloorColour{110, 110, 115};
const Rgb kWallColour{210, 200, 180};

std::vector<Solid> buildSolids(const SceneSpec& spec) {
  const TableSpec& table = spec.table;
  std::vector<Solid> solids;
  const double floor_thickness = 0.01;
  solids.push_back(
      makeBox(Vec3(0, 0, -floor_thickness / 2),
              Vec3(2 * table.floor_half_size, 2 * table.floor_half_size, floor_thickness), 0,
              kFloorLabel, kFloorColour));
  solids.push_back(makeBox(Vec3(0, 0, table.height - table.thickness / 2),
                           Vec3(table.length, table.width, table.thickness), 0, kTableLabel,
                           kTableColour));
  if (table.back_wall) {
    const double wall_thickness = 0.05;
    const double wall_y = table.width / 2 + table.wall_distance + wall_thickness / 2;
    const double wall_height = 2.5;
    solids.push_back(makeBox(Vec3(0, wall_y, wall_height / 2),
                             Vec3(2 * table.floor_half_size, wall_thickness, wall_height), 0,
                             kWallLabel, kWallColour));
  }
  const int palette_size = static_cast<int>(sizeof(kObjectPalette) / sizeof(kObjectPalette[0]));
  for (size_t i = 0; i < spec.objects.size(); ++i) {
    const ObjectSpec& object = spec.objects[i];
    const Rgb& colour = kObjectPalette[i % palette_size];
    const Vec3 bottom(object.position_on_table.x(), object.position_on_table.y(),
                      table.height + object.base_height);
    addObjectSolids(object, bottom, static_cast<int>(i), colour, solids);
  }
  return solids;
}

Eigen::Vector3f sorted(Eigen::Vector3f v) {
  std::sort(v.data(), v.data() + 3, std::greater<float>());
  return v;
}

GroundTruthObject groundTruth(const ObjectSpec& object, const TableSpec& table,
                              const Eigen::Isometry3f& camera_from_world) {
  GroundTruthObject gt;
  gt.type = object.type;
  gt.name = object.name;
  gt.form = object.form;
  gt.height = object.type == ShapeType::Cube ? object.box_size.z() : object.height;
  const Eigen::Vector3f centre_world(object.position_on_table.x(), object.position_on_table.y(),
                                     table.height + object.base_height + object.objectHeight() / 2);
  gt.center = camera_from_world * centre_world;
  Eigen::Matrix3f world_from_object =
      Eigen::AngleAxisf(object.yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  if (object.form == ObjectForm::LyingCan) {  // axis (object z) along the yaw direction
    world_from_object *=
        Eigen::AngleAxisf(static_cast<float>(kPi / 2), Eigen::Vector3f::UnitY()).toRotationMatrix();
  }
  gt.orientation = Eigen::Quaternionf(camera_from_world.linear() * world_from_object).normalized();
  if (object.type == ShapeType::Cube) {
    gt.dimensions = object.box_size;
    gt.sorted_dimensions = sorted(object.box_size);
  } else {
    gt.radius_bottom = object.radius_bottom;
    gt.radius_top = object.type == ShapeType::Cylinder ? object.radius_bottom : object.radius_top;
  }
  return gt;
}

// Active stereo's edge bleeding (file comment, 1a): each pixel within `radius` of a pixel
// nearer by more than `min_jump` takes, with probability 1 - (k - 1) / radius at Chebyshev
// distance k, the depth, label, incidence and colour of the nearest such pixel (the nearest
// of them when several are equally far).
void bleedEdges(int width, int height, int radius, double min_jump, std::vector<double>& depth,
                std::vector<int>& labels, std::vector<double>& cos_incidence,
                std::vector<Rgb>& colours, std::mt19937& rng) {
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  const std::vector<double> source = depth;
  const std::vector<int> source_labels = labels;
  const std::vector<double> source_cos = cos_incidence;
  const std::vector<Rgb> source_colours = colours;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const size_t i = static_cast<size_t>(v) * width + u;
      int best_k = radius + 1;
      size_t best = i;
      for (int dv = -radius; dv <= radius; ++dv) {
        for (int du = -radius; du <= radius; ++du) {
          const int nu = u + du, nv = v + dv, k = std::max(std::abs(du), std::abs(dv));
          if (k == 0 || k > best_k || nu < 0 || nv < 0 || nu >= width || nv >= height) continue;
          const size_t j = static_cast<size_t>(nv) * width + nu;
          if (!std::isfinite(source[j]) || !(source[i] - source[j] > min_jump)) continue;
          if (k < best_k || source[j] < source[best]) {
            best_k = k;
            best = j;
          }
        }
      }
      if (best == i || uniform(rng) >= 1.0f - static_cast<float>(best_k - 1) / radius) continue;
      depth[i] = source[best];
      labels[i] = source_labels[best];
      cos_incidence[i] = source_cos[best];
      colours[i] = source_colours[best];
    }
  }
}

// Active stereo's shadow (file comment, 1b): pixels the right imager, `focal_baseline` / z
// pixels of disparity away, cannot see lose their depth.
void removeStereoShadow(int width, int height, double focal_baseline, std::vector<double>& depth) {
  std::vector<double> disparity(depth.size(), 0.0);
  for (size_t i = 0; i < depth.size(); ++i) {
    if (std::isfinite(depth[i]) && depth[i] > 0) disparity[i] = focal_baseline / depth[i];
  }
  for (int v = 0; v < height; ++v) {
    const double* row = disparity.data() + static_cast<size_t>(v) * width;
    const double row_max = *std::max_element(row, row + width);
    for (int u = 0; u < width; ++u) {
      if (row[u] <= 0) continue;
      for (int u2 = u + 1; u2 < width && u2 - u <= row_max - row[u]; ++u2) {
        if (row[u2] - row[u] >= u2 - u) {
          depth[static_cast<size_t>(v) * width + u] = kInf;
          break;
        }
      }
    }
  }
}

// A unit-variance Gaussian field correlated over `size` x `size` pixels: the box sum of
// independent normals, divided by the root of the number summed (fewer at the image border).
std::vector<float> correlatedNoiseField(int width, int height, int size, std::mt19937& rng) {
  std::normal_distribution<float> standard_normal(0.0f, 1.0f);
  // Integral image with a zero first row and column.
  std::vector<double> integral(static_cast<size_t>(width + 1) * (height + 1), 0.0);
  auto at = [&](int u, int v) -> double& {
    return integral[static_cast<size_t>(v) * (width + 1) + u];
  };
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      at(u + 1, v + 1) = standard_normal(rng) + at(u, v + 1) + at(u + 1, v) - at(u, v);
    }
  }
  std::vector<float> field(static_cast<size_t>(width) * height);
  const int before = (size - 1) / 2, after = size / 2;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const int u0 = std::max(u - before, 0), u1 = std::min(u + after, width - 1) + 1;
      const int v0 = std::max(v - before, 0), v1 = std::min(v + after, height - 1) + 1;
      const double sum = at(u1, v1) - at(u0, v1) - at(u1, v0) + at(u0, v0);
      field[static_cast<size_t>(v) * width + u] =
          static_cast<float>(sum / std::sqrt(static_cast<double>((u1 - u0) * (v1 - v0))));
    }
  }
  return field;
}

}  // namespace

// ---- sensors ----

const char* sensorName(SensorModel sensor) {
  return sensor == SensorModel::RealSenseD435 ? "realsense" : "kinect";
}

bool parseSensorName(const std::string& text, SensorModel& sensor) {
  if (text == "kinect" || text == "kinect-v1") {
    sensor = SensorModel::KinectV1;
  } else if (text == "realsense" || text == "d435") {
    sensor = SensorModel::RealSenseD435;
  } else {
    return false;
  }
  return true;
}

NoiseModel NoiseModel::realSenseD435() {
  NoiseModel model;
  model.lateral_sigma_px = 0.3f;
  model.flying_pixel_fraction = 0.1f;  // the correlation window bleeds edges instead
  // Depth sigma z^2 * 0.08 px / (385 px * 0.05 m) = 4.16 mm * z^2, shared between per-pixel
  // noise (3.0 mm) and speckle (2.9 mm), which add in quadrature.
  model.axial_sigma_base = 0.0f;
  model.axial_sigma_quadratic = 0.0030f;
  model.axial_reference_range = 0.0f;
  model.speckle = true;
  model.speckle_sigma_quadratic = 0.0029f;
  model.speckle_size_px = 5;
  model.baseline = 0.05f;
  model.disparity_step_px = 1.0f / 32;  // 5 bits of subpixel disparity
  model.edge_bleeding = true;
  model.edge_bleed_px = 3;
  model.stereo_shadow = true;
  model.dropout_probability = 0.01f;
  model.min_range = 0.28f;
  model.max_range = 4.0f;
  return model;
}

void setSensor(SceneSpec& spec, SensorModel sensor) {
  const bool realsense = sensor == SensorModel::RealSenseD435;
  spec.camera = realsense ? CameraIntrinsics::realSenseD435() : CameraIntrinsics();
  spec.noise = realsense ? NoiseModel::realSenseD435() : NoiseModel::kinectV1();
}

// ---- objects ----

Eigen::Vector2f ObjectSpec::footprintHalfExtents() const {
  if (type == ShapeType::Cube || form == ObjectForm::LyingCan) {
    const float length = form == ObjectForm::LyingCan ? height : box_size.x();
    const float width = form == ObjectForm::LyingCan ? 2 * radius_bottom : box_size.y();
    const float c = std::abs(std::cos(yaw)), s = std::abs(std::sin(yaw));
    return {c * length / 2 + s * width / 2, s * length / 2 + c * width / 2};
  }
  const float r = footprintRadius();
  return {r, r};
}

float ObjectSpec::footprintRadius() const {
  if (type == ShapeType::Cube) return box_size.head<2>().norm() / 2;
  if (form == ObjectForm::LyingCan) return Eigen::Vector2f(height / 2, radius_bottom).norm();
  if (form == ObjectForm::Mug) return radius_bottom + static_cast<float>(kHandleReach);
  return type == ShapeType::Cone ? std::max(radius_bottom, radius_top) : radius_bottom;
}

namespace {
ObjectSpec boxObject(const char* name, float length, float width, float height) {
  ObjectSpec o;
  o.type = ShapeType::Cube;
  o.box_size = {length, width, height};
  o.height = height;
  o.name = name;
  return o;
}
ObjectSpec roundObject(const char* name, ShapeType type, float r_bottom, float r_top, float h) {
  ObjectSpec o;
  o.type = type;
  o.radius_bottom = r_bottom;
  o.radius_top = r_top;
  o.height = h;
  o.name = name;
  return o;
}
}  // namespace

ObjectSpec milkTeaBox() { return boxObject("milk-tea box", 0.15f, 0.095f, 0.05f); }
ObjectSpec teapotBox() { return boxObject("teapot box", 0.175f, 0.12f, 0.10f); }
ObjectSpec steelMug() { return roundObject("mug", ShapeType::Cylinder, 0.0415f, 0.0415f, 0.16f); }
ObjectSpec beaker() { return roundObject("beaker", ShapeType::Cone, 0.03f, 0.0375f, 0.18f); }

const char* everydayKindName(EverydayKind kind) {
  switch (kind) {
    case EverydayKind::Bottle:
      return "bottle";
    case EverydayKind::FlatBottle:
      return "flat bottle";
    case EverydayKind::ShortWideCan:
      return "short wide can";
    case EverydayKind::Marker:
      return "marker";
    case EverydayKind::SoupCan:
      return "soup can";
    case EverydayKind::LyingCan:
      return "lying can";
    case EverydayKind::Bowl:
      return "bowl";
    case EverydayKind::Mug:
      return "mug";
    case EverydayKind::BorderBox:
      return "border box";
  }
  return "";
}

ObjectSpec everydayObject(EverydayKind kind, int variant) {
  const char* name = everydayKindName(kind);
  const bool second = variant % 2 != 0;
  auto formed = [](ObjectSpec object, ObjectForm form) {
    object.form = form;
    return object;
  };
  switch (kind) {
    case EverydayKind::Bottle:
      return formed(second ? roundObject(name, ShapeType::Cylinder, 0.04f, 0.04f, 0.26f)
                           : roundObject(name, ShapeType::Cylinder, 0.0325f, 0.0325f, 0.205f),
                    ObjectForm::Bottle);
    case EverydayKind::FlatBottle:
      return formed(
          second ? boxObject(name, 0.098f, 0.065f, 0.25f) : boxObject(name, 0.085f, 0.05f, 0.175f),
          ObjectForm::FlatBottle);
    case EverydayKind::ShortWideCan:
      return roundObject(name, ShapeType::Cylinder, 0.0425f, 0.0425f, 0.033f);
    case EverydayKind::Marker:
      return roundObject(name, ShapeType::Cylinder, 0.009f, 0.009f, 0.14f);
    case EverydayKind::SoupCan:
      return roundObject(name, ShapeType::Cylinder, 0.033f, 0.033f, 0.101f);
    case EverydayKind::LyingCan:
      return formed(roundObject(name, ShapeType::Cylinder, 0.033f, 0.033f, 0.101f),
                    ObjectForm::LyingCan);
    case EverydayKind::Bowl:
      return formed(roundObject(name, ShapeType::Cone, 0.04f, 0.075f, 0.065f), ObjectForm::Bowl);
    case EverydayKind::Mug:
      return formed(roundObject(name, ShapeType::Cylinder, 0.041f, 0.041f, 0.095f),
                    ObjectForm::Mug);
    case EverydayKind::BorderBox:
      return boxObject(name, 0.089f, 0.038f, 0.175f);
  }
  return ObjectSpec();
}

// ---- camera ----

Eigen::Vector3f lookAtPoint(const SceneSpec& spec) {
  if (spec.placement.fixed_look_at) {
    return {spec.placement.look_at.x(), spec.placement.look_at.y(), spec.table.height};
  }
  Eigen::Vector2f mean = Eigen::Vector2f::Zero();
  for (const auto& object : spec.objects) mean += object.position_on_table;
  if (!spec.objects.empty()) mean /= static_cast<float>(spec.objects.size());
  return {mean.x(), mean.y(), spec.table.height};
}

Eigen::Isometry3f cameraPose(const SceneSpec& spec) {
  const float tilt = degToRad(spec.placement.tilt_deg);
  const float yaw = degToRad(spec.placement.yaw_deg);
  const Eigen::Vector3f forward(std::cos(tilt) * std::cos(yaw), std::cos(tilt) * std::sin(yaw),
                                -std::sin(tilt));
  // forward x up, normalised; written out so that a vertical camera (tilt 90) stays defined.
  const Eigen::Vector3f right(std::sin(yaw), -std::cos(yaw), 0.0f);
  const Eigen::Vector3f down = forward.cross(right);
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
  pose.linear().col(0) = right;
  pose.linear().col(1) = down;
  pose.linear().col(2) = forward;
  pose.translation() = lookAtPoint(spec) - spec.placement.distance * forward;
  return pose;
}

// ---- rendering ----

RenderedScene renderScene(const SceneSpec& spec) {
  const CameraIntrinsics& cam = spec.camera;
  const NoiseModel& noise = spec.noise;
  const bool noisy = noise.enabled;
  RenderedScene scene;
  scene.spec = spec;
  scene.world_from_camera = cameraPose(spec);
  const Eigen::Isometry3f camera_from_world = scene.world_from_camera.inverse();

  const std::vector<Solid> solids = buildSolids(spec);
  const Vec3 ray_origin = scene.world_from_camera.translation().cast<double>();
  const Mat3 world_from_camera = scene.world_from_camera.linear().cast<double>();

  const int width = std::max(cam.width, 0), height = std::max(cam.height, 0);
  const size_t pixels = static_cast<size_t>(width) * height;
  std::mt19937 rng(spec.seed);
  // float distributions: one engine call per uniform (double needs two).
  std::normal_distribution<float> standard_normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);

  // Pass 1: clean depth (t along d = (x, y, 1) is the optical z), label, incidence, colour.
  std::vector<double> depth(pixels, kInf);
  std::vector<int> labels(pixels, kNoReturn);
  std::vector<double> cos_incidence(pixels, 0.0);
  std::vector<Rgb> colours(pixels, Rgb{0, 0, 0});
  const bool jitter = noisy && noise.lateral_noise && noise.lateral_sigma_px > 0;
  // Each ray is tested only against the solids whose image rectangle holds its pixel.
  const double jitter_margin_px = 2.0 + (jitter ? 6.0 * noise.lateral_sigma_px : 0.0);
  std::vector<PixelRect> rects;
  for (const Solid& solid : solids) {
    rects.push_back(projectedRect(solid, scene.world_from_camera.inverse().cast<double>(), cam,
                                  jitter_margin_px));
  }
  // Objects met by the ray of each pixel, hidden or not (unoccluded_pixels); pixel centres only.
  std::vector<int> unoccluded(spec.objects.size(), 0);
  // Casts the ray through image point (pu, pv) for pixel i (u, v).
  auto castRay = [&](int u, int v, double pu, double pv, size_t i, bool count_unoccluded) {
    const Vec3 dir = world_from_camera * Vec3((pu - cam.cx) / cam.fx, (pv - cam.cy) / cam.fy, 1.0);
    Hit hit;
    const Solid* hit_solid = nullptr;
    int last_met = kNoReturn;  // an object's solids come one after another
    for (size_t k = 0; k < solids.size(); ++k) {
      if (!rects[k].contains(u, v)) continue;
      const double before = hit.t;
      if (count_unoccluded && solids[k].label >= 0 && solids[k].label != last_met) {
        Hit own;
        solids[k].intersect(ray_origin, dir, own);
        if (own.t < kInf) ++unoccluded[last_met = solids[k].label];
      }
      solids[k].intersect(ray_origin, dir, hit);
      if (hit.t < before) hit_solid = &solids[k];
    }
    depth[i] = hit.t;
    labels[i] = hit.label;
    cos_incidence[i] = hit_solid ? std::abs(hit.normal.dot(dir.normalized())) : 0.0;
    const float shade = static_cast<float>(0.35 + 0.65 * cos_incidence[i]);
    for (int c = 0; c < 3; ++c) colours[i][c] = hit_solid ? hit_solid->colour[c] * shade : 0.0f;
  };
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) castRay(u, v, u, v, static_cast<size_t>(v) * width + u, true);
  }
  // Lateral noise shows only where the surface changes: recast the rays of pixels next to a
  // label change or a depth jump through jittered image points (saves ~0.6 M normal draws).
  if (jitter) {
    const std::vector<double> sharp_depth = depth;
    const std::vector<int> sharp_labels = labels;
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        const size_t i = static_cast<size_t>(v) * width + u;
        bool edge = false;
        for (int dv = -1; dv <= 1 && !edge; ++dv) {
          for (int du = -1; du <= 1 && !edge; ++du) {
            const int nu = u + du, nv = v + dv;
            if (nu < 0 || nv < 0 || nu >= width || nv >= height) continue;
            const size_t j = static_cast<size_t>(nv) * width + nu;
            edge = sharp_labels[j] != sharp_labels[i] ||
                   std::abs(sharp_depth[j] - sharp_depth[i]) > noise.flying_min_jump;
          }
        }
        if (!edge) continue;
        const double pu = u + noise.lateral_sigma_px * standard_normal(rng);
        const double pv = v + noise.lateral_sigma_px * standard_normal(rng);
        castRay(u, v, pu, pv, i, false);
      }
    }
  }

  const double focal_baseline = cam.fx * noise.baseline;
  if (noisy && noise.edge_bleeding && noise.edge_bleed_px > 0) {
    bleedEdges(width, height, noise.edge_bleed_px, noise.flying_min_jump, depth, labels,
               cos_incidence, colours, rng);
  }
  if (noisy && noise.stereo_shadow) removeStereoShadow(width, height, focal_baseline, depth);
  std::vector<float> speckle;
  if (noisy && noise.speckle) {
    speckle = correlatedNoiseField(width, height, std::max(noise.speckle_size_px, 1), rng);
  }

  // Pass 2: sensor effects on the depth image, in the documented order.
  const double min_cos_incidence = std::cos(degToRad(noise.max_incidence_deg));
  std::vector<double> measured(depth);
  for (int v = 0; v < height && noisy; ++v) {
    for (int u = 0; u < width; ++u) {
      const size_t i = static_cast<size_t>(v) * width + u;
      double z = depth[i];
      if (!std::isfinite(z)) continue;
      if (noise.flying_pixels && noise.flying_pixel_fraction > 0) {
        double far_neighbour = z, jump = 0;
        const int du[] = {1, -1, 0, 0}, dv[] = {0, 0, 1, -1};
        for (int n = 0; n < 4; ++n) {
          const int nu = u + du[n], nv = v + dv[n];
          if (nu < 0 || nv < 0 || nu >= width || nv >= height) continue;
          const double zn = depth[static_cast<size_t>(nv) * width + nu];
          if (std::isfinite(zn) && std::abs(zn - z) > jump) {
            jump = std::abs(zn - z);
            far_neighbour = zn;
          }
        }
        if (jump > noise.flying_min_jump && uniform(rng) < noise.flying_pixel_fraction) {
          z = std::min(z, far_neighbour) + uniform(rng) * jump;
        }
      }
      if (noise.axial_noise) z += noise.axialSigma(static_cast<float>(z)) * standard_normal(rng);
      if (!speckle.empty()) z += noise.speckle_sigma_quadratic * z * z * speckle[i];
      if (noise.disparity_quantisation && noise.disparity_step_px > 0 && z > 0) {
        const double step = noise.disparity_step_px;
        const double disparity = std::round(focal_baseline / z / step) * step;
        z = disparity > 0 ? focal_baseline / disparity : kInf;
      }
      if (noise.grazing_dropout && cos_incidence[i] < min_cos_incidence) z = kInf;
      if (noise.random_dropout && uniform(rng) < noise.dropout_probability) z = kInf;
      measured[i] = z;
    }
  }

  // Back-projection through the pixel centres; range limits.
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>();
  cloud->width = static_cast<uint32_t>(width);
  cloud->height = static_cast<uint32_t>(height);
  cloud->is_dense = false;
  cloud->points.resize(pixels);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  scene.objects.reserve(spec.objects.size());
  for (const auto& object : spec.objects) {
    scene.objects.push_back(groundTruth(object, spec.table, camera_from_world));
    scene.objects.back().unoccluded_pixels = unoccluded[scene.objects.size() - 1];
  }
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const size_t i = static_cast<size_t>(v) * width + u;
      pcl::PointXYZRGB& p = cloud->points[i];
      const double z = measured[i];
      if (!std::isfinite(z) || z < noise.min_range || z > noise.max_range) {
        p.x = p.y = p.z = nan;
        p.r = p.g = p.b = 0;
        labels[i] = kNoReturn;
        continue;
      }
      p.x = static_cast<float>((u - cam.cx) * z / cam.fx);
      p.y = static_cast<float>((v - cam.cy) * z / cam.fy);
      p.z = static_cast<float>(z);
      p.r = static_cast<uint8_t>(std::clamp(colours[i][0], 0.0f, 255.0f));
      p.g = static_cast<uint8_t>(std::clamp(colours[i][1], 0.0f, 255.0f));
      p.b = static_cast<uint8_t>(std::clamp(colours[i][2], 0.0f, 255.0f));
      if (labels[i] >= 0) {
        GroundTruthObject& object = scene.objects[labels[i]];
        ++object.visible_pixels;
        object.at_image_border |= u == 0 || v == 0 || u == width - 1 || v == height - 1;
      }
    }
  }
  scene.cloud = cloud;
  scene.labels = std::move(labels);

  scene.up = camera_from_world.linear() * Eigen::Vector3f::UnitZ();
  scene.table_plane.normal = scene.up;
  scene.table_plane.d =
      -scene.up.dot(camera_from_world * Eigen::Vector3f(0.0f, 0.0f, spec.table.height));
  return scene;
}

// ---- scene generators ----

namespace {

ObjectSpec randomObject(std::mt19937& rng, float paper_probability) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  auto between = [&](float lo, float hi) { return lo + (hi - lo) * unit(rng); };
  if (unit(rng) < paper_probability) {
    const ObjectSpec presets[] = {milkTeaBox(), teapotBox(), steelMug(), beaker()};
    return presets[std::uniform_int_distribution<int>(0, 3)(rng)];
  }
  ObjectSpec o;
  switch (std::uniform_int_distribution<int>(0, 2)(rng)) {
    case 0:
      o.type = ShapeType::Cube;
      o.box_size = {between(0.05f, 0.25f), between(0.04f, 0.20f), between(0.03f, 0.25f)};
      o.height = o.box_size.z();
      o.name = "random box";
      break;
    case 1:
      o.type = ShapeType::Cylinder;
      o.radius_bottom = o.radius_top = between(0.025f, 0.08f);
      o.height = between(0.05f, 0.25f);
      o.name = "random cylinder";
      break;
    default: {
      o.type = ShapeType::Cone;
      o.radius_bottom = between(0.025f, 0.07f);
      o.height = between(0.06f, 0.25f);
      // |dr/dh| well above the fitter's cylinder limit, either way up.
      const float slope = between(0.04f, 0.2f) * (unit(rng) < 0.5f ? -1.0f : 1.0f);
      o.radius_top = std::clamp(o.radius_bottom + slope * o.height, 0.015f, 0.1f);
      if (std::abs(o.radius_top - o.radius_bottom) < 0.04f * o.height) {
        o.radius_top = o.radius_bottom + 0.04f * o.height;
      }
      o.name = "random cone";
      break;
    }
  }
  return o;
}

// Every object's centre projects inside the image by `margin` pixels, in front of the camera.
bool objectsInView(const SceneSpec& spec, float margin) {
  const Eigen::Isometry3f camera_from_world = cameraPose(spec).inverse();
  for (const auto& object : spec.objects) {
    const Eigen::Vector3f p =
        camera_from_world *
        Eigen::Vector3f(object.position_on_table.x(), object.position_on_table.y(),
                        spec.table.height + object.base_height + object.objectHeight() / 2);
    if (p.z() < spec.noise.min_range + 0.05f) return false;
    const float u = spec.camera.fx * p.x() / p.z() + spec.camera.cx;
    const float v = spec.camera.fy * p.y() / p.z() + spec.camera.cy;
    if (u < margin || v < margin || u > spec.camera.width - 1 - margin ||
        v > spec.camera.height - 1 - margin) {
      return false;
    }
  }
  return true;
}

}  // namespace

SceneSpec randomScene(std::mt19937& rng, const RandomSceneOptions& options) {
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  auto between = [&](float lo, float hi) { return lo + (hi - lo) * unit(rng); };
  const int min_objects = std::max(0, options.min_objects);
  const int max_objects = std::max(min_objects, options.max_objects);
  const float half_length = options.table.length / 2 - options.edge_margin;
  const float half_width = options.table.width / 2 - options.edge_margin;

  SceneSpec spec;
  for (int attempt = 0; attempt < 500; ++attempt) {
    spec = SceneSpec();
    spec.camera = options.camera;
    spec.table = options.table;
    spec.noise = options.noise;
    const int count = std::uniform_int_distribution<int>(min_objects, max_objects)(rng);
    bool placed_all = true;
    for (int k = 0; k < count && placed_all; ++k) {
      placed_all = false;
      for (int tries = 0; tries < 100 && !placed_all; ++tries) {
        ObjectSpec object = randomObject(rng, options.paper_object_probability);
        object.yaw = between(0.0f, 2.0f * static_cast<float>(kPi));
        const Eigen::Vector2f extent = object.footprintHalfExtents();
        if (extent.x() > half_length || extent.y() > half_width) continue;
        object.position_on_table = {between(-half_length + extent.x(), half_length - extent.x()),
                                    between(-half_width + extent.y(), half_width - extent.y())};
        bool overlaps = false;
        for (const auto& other : spec.objects) {
          overlaps |= (object.position_on_table - other.position_on_table).norm() <
                      object.footprintRadius() + other.footprintRadius() + options.min_gap;
        }
        if (overlaps) continue;
        spec.objects.push_back(object);
        placed_all = true;
      }
    }
    spec.placement.distance = between(options.min_distance, options.max_distance);
    spec.placement.tilt_deg = between(options.min_tilt_deg, options.max_tilt_deg);
    spec.placement.yaw_deg = between(options.min_yaw_deg, options.max_yaw_deg);
    spec.seed = static_cast<uint32_t>(rng());
    if (placed_all && objectsInView(spec, options.image_margin_px)) break;
  }
  return spec;
}

SceneSpec paperScene(const CameraPlacement& placement, const NoiseModel& noise, uint32_t seed) {
  SceneSpec spec;
  spec.placement = placement;
  spec.noise = noise;
  spec.seed = seed;
  // A row along the table's long edge, slightly staggered, centred on the table.
  struct Placed {
    ObjectSpec object;
    float x, y, yaw_deg;
  };
  const Placed layout[] = {{milkTeaBox(), -0.30f, 0.04f, 15.0f},
                           {steelMug(), -0.10f, -0.04f, 0.0f},
                           {teapotBox(), 0.10f, 0.04f, -25.0f},
                           {beaker(), 0.30f, -0.04f, 0.0f}};
  for (const auto& placed : layout) {
    ObjectSpec object = placed.object;
    object.position_on_table = {placed.x, placed.y};
    object.yaw = degToRad(placed.yaw_deg);
    spec.objects.push_back(object);
  }
  return spec;
}

SceneSpec jitteredPaperScene(std::mt19937& rng) {
  std::uniform_real_distribution<float> distance(0.6f, 1.5f), tilt(20.0f, 60.0f), yaw(0.0f, 360.0f),
      jitter(-0.015f, 0.015f), object_yaw(0.0f, static_cast<float>(kPi));
  CameraPlacement placement{distance(rng), tilt(rng), yaw(rng)};
  SceneSpec spec = paperScene(placement, NoiseModel(), static_cast<uint32_t>(rng()));
  std::vector<Eigen::Vector2f> slots = {
      {-0.13f, -0.13f}, {-0.13f, 0.13f}, {0.13f, -0.13f}, {0.13f, 0.13f}};
  std::shuffle(slots.begin(), slots.end(), rng);
  for (size_t i = 0; i < spec.objects.size(); ++i) {
    spec.objects[i].position_on_table = slots[i] + Eigen::Vector2f(jitter(rng), jitter(rng));
    spec.objects[i].yaw = object_yaw(rng);
  }
  return spec;
}

namespace {

// Where the ray through pixel (u, v) meets the horizontal plane at world height z; false when
// it points away from it.
bool pixelOnPlane(const SceneSpec& spec, float u, float v, float z, Eigen::Vector2f& xy) {
  const Eigen::Isometry3f pose = cameraPose(spec);
  const Eigen::Vector3f dir =
      pose.linear() * Eigen::Vector3f((u - spec.camera.cx) / spec.camera.fx,
                                      (v - spec.camera.cy) / spec.camera.fy, 1);
  const float t = (z - pose.translation().z()) / dir.z();
  if (!(t > 0)) return false;
  xy = (pose.translation() + t * dir).head<2>();
  return true;
}

}  // namespace

SceneSpec everydayScene(uint32_t seed, SensorModel sensor) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  auto between = [&](float lo, float hi) { return lo + (hi - lo) * unit(rng); };
  SceneSpec spec;
  setSensor(spec, sensor);
  spec.table.length = 1.6f;
  spec.table.width = 1.0f;
  spec.seed = static_cast<uint32_t>(rng());
  const float camera_height = between(0.5f, 0.7f), tilt = between(40.0f, 60.0f);
  spec.placement.tilt_deg = tilt;
  spec.placement.distance = camera_height / std::sin(degToRad(tilt));
  spec.placement.yaw_deg = between(0.0f, 360.0f);
  spec.placement.fixed_look_at = true;
  spec.placement.look_at = {between(-0.15f, 0.15f), between(-0.1f, 0.1f)};
  const Eigen::Isometry3f camera_from_world = cameraPose(spec).inverse();

  const float edge_margin = 0.05f, min_gap = 0.03f, image_margin_px = 30.0f;
  // The border box first (it has the fewest places), then 4 of the other kinds.
  std::vector<int> kinds(kEverydayKinds - 1);
  std::iota(kinds.begin(), kinds.end(), 0);
  std::shuffle(kinds.begin(), kinds.end(), rng);
  kinds.resize(4);
  kinds.insert(kinds.begin(), static_cast<int>(EverydayKind::BorderBox));
  const float min_range = std::max(0.4f, spec.noise.min_range + 0.1f);
  for (const int kind_index : kinds) {
    const auto kind = static_cast<EverydayKind>(kind_index);
    ObjectSpec object = everydayObject(kind, static_cast<int>(rng() % 2));
    for (int tries = 0; tries < 500; ++tries) {
      object.yaw = between(0.0f, 2.0f * static_cast<float>(kPi));
      const Eigen::Vector2f extent = object.footprintHalfExtents();
      const float centre_z = spec.table.height + object.objectHeight() / 2;
      if (kind == EverydayKind::BorderBox) {  // centre on the left, right or bottom border
        const int side = static_cast<int>(rng() % 3);
        const float w = static_cast<float>(spec.camera.width - 1),
                    h = static_cast<float>(spec.camera.height - 1);
        const float u = side == 2 ? between(0.1f, 0.9f) * w : (side == 0 ? 0.0f : w);
        const float v = side == 2 ? h : between(0.2f, 1.0f) * h;
        if (!pixelOnPlane(spec, u, v, centre_z, object.position_on_table)) continue;
      } else {
        object.position_on_table = {between(-0.8f, 0.8f), between(-0.5f, 0.5f)};
      }
      const Eigen::Vector2f& p = object.position_on_table;
      if (std::abs(p.x()) + extent.x() > spec.table.length / 2 - edge_margin ||
          std::abs(p.y()) + extent.y() > spec.table.width / 2 - edge_margin) {
        continue;
      }
      bool overlaps = false;
      for (const auto& other : spec.objects) {
        overlaps |= (p - other.position_on_table).norm() <
                    object.footprintRadius() + other.footprintRadius() + min_gap;
      }
      const Eigen::Vector3f centre = camera_from_world * Eigen::Vector3f(p.x(), p.y(), centre_z);
      const float range = centre.norm();
      if (overlaps || range < min_range || range > 1.2f) continue;
      const float u = spec.camera.fx * centre.x() / centre.z() + spec.camera.cx;
      const float v = spec.camera.fy * centre.y() / centre.z() + spec.camera.cy;
      const bool inside = u >= image_margin_px && v >= image_margin_px &&
                          u <= spec.camera.width - 1 - image_margin_px &&
                          v <= spec.camera.height - 1 - image_margin_px;
      if (kind != EverydayKind::BorderBox && !inside) continue;
      spec.objects.push_back(object);
      break;
    }
  }
  // Half of the tables stand 0-0.2 m before a wall (on real frames its clusters became large
  // cones), when the camera is on this side of it.
  spec.table.wall_distance = between(0.0f, 0.2f);
  const float wall_y = spec.table.width / 2 + spec.table.wall_distance;
  spec.table.back_wall = unit(rng) < 0.5f && cameraPose(spec).translation().y() < wall_y - 0.1f;
  return spec;
}

// ---- output ----

namespace {

template <typename Vector>
std::string jsonArray(const Vector& v) {
  std::ostringstream out;
  out << std::setprecision(7) << '[';
  for (int i = 0; i < v.size(); ++i) out << (i ? ", " : "") << v[i];
  out << ']';
  return out.str();
}

std::string jsonQuaternion(const Eigen::Quaternionf& q) {
  return jsonArray(Eigen::Vector4f(q.x(), q.y(), q.z(), q.w()));
}

const char* formName(ObjectForm form) {
  switch (form) {
    case ObjectForm::Plain:
      return "plain";
    case ObjectForm::Bottle:
      return "bottle";
    case ObjectForm::FlatBottle:
      return "flat bottle";
    case ObjectForm::Bowl:
      return "bowl";
    case ObjectForm::Mug:
      return "mug";
    case ObjectForm::LyingCan:
      return "lying can";
  }
  return "";
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + '"';
}

}  // namespace

std::string groundTruthJson(const RenderedScene& scene) {
  const SceneSpec& spec = scene.spec;
  const NoiseModel& n = spec.noise;
  const Eigen::Quaternionf camera_rotation(scene.world_from_camera.linear());
  std::ostringstream out;
  out << std::setprecision(7) << std::boolalpha;
  out << "{\n  \"frame\": \"camera optical (x right, y down, z forward), metres\",\n";
  out << "  \"seed\": " << spec.seed << ",\n";
  out << "  \"camera\": {\"width\": " << spec.camera.width << ", \"height\": " << spec.camera.height
      << ", \"fx\": " << spec.camera.fx << ", \"fy\": " << spec.camera.fy
      << ", \"cx\": " << spec.camera.cx << ", \"cy\": " << spec.camera.cy
      << ",\n    \"distance\": " << spec.placement.distance
      << ", \"tilt_deg\": " << spec.placement.tilt_deg
      << ", \"yaw_deg\": " << spec.placement.yaw_deg
      << ",\n    \"position_world\": " << jsonArray(scene.world_from_camera.translation())
      << ", \"orientation_world_xyzw\": " << jsonQuaternion(camera_rotation) << "},\n";
  out << "  \"noise\": {\"enabled\": " << n.enabled << ", \"lateral_noise\": " << n.lateral_noise
      << ", \"lateral_sigma_px\": " << n.lateral_sigma_px
      << ", \"flying_pixels\": " << n.flying_pixels
      << ", \"flying_pixel_fraction\": " << n.flying_pixel_fraction
      << ", \"flying_min_jump\": " << n.flying_min_jump
      << ",\n    \"axial_noise\": " << n.axial_noise
      << ", \"axial_sigma_base\": " << n.axial_sigma_base
      << ", \"axial_sigma_quadratic\": " << n.axial_sigma_quadratic
      << ", \"axial_reference_range\": " << n.axial_reference_range
      << ",\n    \"disparity_quantisation\": " << n.disparity_quantisation
      << ", \"baseline\": " << n.baseline << ", \"disparity_step_px\": " << n.disparity_step_px
      << ", \"grazing_dropout\": " << n.grazing_dropout
      << ", \"max_incidence_deg\": " << n.max_incidence_deg
      << ",\n    \"random_dropout\": " << n.random_dropout
      << ", \"dropout_probability\": " << n.dropout_probability
      << ", \"min_range\": " << n.min_range << ", \"max_range\": " << n.max_range
      << ",\n    \"edge_bleeding\": " << n.edge_bleeding
      << ", \"edge_bleed_px\": " << n.edge_bleed_px << ", \"stereo_shadow\": " << n.stereo_shadow
      << ", \"speckle\": " << n.speckle
      << ", \"speckle_sigma_quadratic\": " << n.speckle_sigma_quadratic
      << ", \"speckle_size_px\": " << n.speckle_size_px << "},\n";
  out << "  \"table\": {\"length\": " << spec.table.length << ", \"width\": " << spec.table.width
      << ", \"height\": " << spec.table.height << ", \"thickness\": " << spec.table.thickness
      << ", \"back_wall\": " << spec.table.back_wall
      << ",\n    \"plane\": " << jsonArray(scene.table_plane.coefficients()) << "},\n";
  out << "  \"up\": " << jsonArray(scene.up) << ",\n";
  out << "  \"objects\": [";
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const GroundTruthObject& o = scene.objects[i];
    const ObjectSpec& s = spec.objects[i];
    out << (i ? "," : "") << "\n    {\"type\": \"" << shapeTypeName(o.type)
        << "\", \"name\": " << jsonString(o.name) << ", \"form\": \"" << formName(o.form)
        << "\", \"visible_pixels\": " << o.visible_pixels
        << ", \"unoccluded_pixels\": " << o.unoccluded_pixels
        << ", \"at_image_border\": " << o.at_image_border
        << ",\n     \"center\": " << jsonArray(o.center)
        << ", \"orientation_xyzw\": " << jsonQuaternion(o.orientation)
        << ", \"axis\": " << jsonArray(o.axis());
    if (o.type == ShapeType::Cube) {
      out << ",\n     \"dimensions\": " << jsonArray(o.dimensions)
          << ", \"sorted_dimensions\": " << jsonArray(o.sorted_dimensions);
    } else {
      out << ",\n     \"radius_bottom\": " << o.radius_bottom
          << ", \"radius_top\": " << o.radius_top;
    }
    out << ", \"height\": " << o.height
        << ",\n     \"position_on_table\": " << jsonArray(s.position_on_table)
        << ", \"base_height\": " << s.base_height << ", \"yaw_deg\": " << s.yaw * 180.0 / kPi
        << "}";
  }
  out << "\n  ]\n}\n";
  return out.str();
}

bool writePcd(const RenderedScene& scene, const std::string& path) {
  if (!scene.cloud) return false;
  return pcl::io::savePCDFileBinary(path, *scene.cloud) == 0;
}

bool writeGroundTruthJson(const RenderedScene& scene, const std::string& path) {
  std::ofstream file(path);
  file << groundTruthJson(scene);
  return static_cast<bool>(file);
}

}  // namespace sim
}  // namespace tabletop_shapes
