// Known-answer clouds for unit tests: the visible surface of a box, cylinder or truncated cone
// standing on the plane z = 0 (table frame: z up), seen from a camera position, with optional
// Gaussian noise. Visibility of a convex solid = surface normal faces the camera; the bottom
// face (on the table) is never visible. Shared by all core tests; header-only on purpose.
#pragma once

#include "tabletop_shapes/core/types.h"

#include <random>

namespace tabletop_shapes {
namespace synthetic {

struct Sampler {
  Eigen::Vector3f camera{0.0f, -0.8f, 0.6f};  // table frame
  float spacing = 0.003f;                     // surface sample spacing [m]
  float noise_sigma = 0.0f;                   // Gaussian noise per coordinate [m]
  unsigned seed = 1;
};

// Surfaces as the preprocessing leaves them: points 5 mm apart (its voxel grid), 1 mm noise.
inline Sampler voxelGridSampler() {
  Sampler s;
  s.spacing = 0.005f;
  s.noise_sigma = 0.001f;
  return s;
}

inline void addIfVisible(const Eigen::Vector3f& p, const Eigen::Vector3f& n, const Sampler& s,
                         std::mt19937& rng, Cloud& out) {
  if (n.dot(s.camera - p) <= 0.0f) return;
  std::normal_distribution<float> noise(0.0f, s.noise_sigma > 0 ? s.noise_sigma : 1.0f);
  Eigen::Vector3f q = p;
  if (s.noise_sigma > 0) q += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
  out.push_back(Point(q.x(), q.y(), q.z()));
}

// Box with edges (lx, ly, lz), bottom centre at (cx, cy, 0), rotated by yaw about z.
inline CloudPtr box(const Eigen::Vector3f& size, const Eigen::Vector2f& bottom_centre, float yaw,
                    const Sampler& s) {
  std::mt19937 rng(s.seed);
  auto out = std::make_shared<Cloud>();
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Eigen::Vector3f c(bottom_centre.x(), bottom_centre.y(), size.z() / 2);
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {-1, 1}) {
      if (axis == 2 && sign < 0) continue;  // bottom face stands on the table
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      Eigen::Vector3f n_local = Eigen::Vector3f::Zero();
      n_local[axis] = static_cast<float>(sign);
      for (float a = -size[u] / 2; a <= size[u] / 2 + 1e-6f; a += s.spacing) {
        for (float b = -size[v] / 2; b <= size[v] / 2 + 1e-6f; b += s.spacing) {
          Eigen::Vector3f local = Eigen::Vector3f::Zero();
          local[axis] = sign * size[axis] / 2;
          local[u] = a;
          local[v] = b;
          addIfVisible(c + R * local, R * n_local, s, rng, *out);
        }
      }
    }
  }
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  return out;
}

// Truncated cone (r_bottom at z = 0, r_top at z = height) with axis along z through (cx, cy);
// a cylinder when r_bottom == r_top. Side and top disc.
inline CloudPtr roundObject(float r_bottom, float r_top, float height,
                            const Eigen::Vector2f& centre, const Sampler& s) {
  std::mt19937 rng(s.seed);
  auto out = std::make_shared<Cloud>();
  const float slope = (r_top - r_bottom) / height;  // dr/dz
  for (float z = 0.0f; z <= height + 1e-6f; z += s.spacing) {
    const float r = r_bottom + slope * z;
    const int steps = std::max(8, static_cast<int>(2 * kPi * r / s.spacing));
    for (int i = 0; i < steps; ++i) {
      const float t = static_cast<float>(2 * kPi * i / steps);
      const Eigen::Vector3f p(centre.x() + r * std::cos(t), centre.y() + r * std::sin(t), z);
      const Eigen::Vector3f n = Eigen::Vector3f(std::cos(t), std::sin(t), -slope).normalized();
      addIfVisible(p, n, s, rng, *out);
    }
  }
  for (float rr = 0.0f; rr <= r_top; rr += s.spacing) {
    const int steps = std::max(1, static_cast<int>(2 * kPi * rr / s.spacing));
    for (int i = 0; i < steps; ++i) {
      const float t = static_cast<float>(2 * kPi * i / steps);
      addIfVisible({centre.x() + rr * std::cos(t), centre.y() + rr * std::sin(t), height},
                   Eigen::Vector3f::UnitZ(), s, rng, *out);
    }
  }
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  return out;
}

// A bowl: the truncated cone (r_bottom at z = 0, r_top at z = height; open at the top) with
// walls `wall` thick. The outer wall where it faces the camera, and the inside (inner wall and
// floor) where the camera sees it over the rim.
inline CloudPtr bowl(float r_bottom, float r_top, float height, float wall,
                     const Eigen::Vector2f& centre, const Sampler& s) {
  std::mt19937 rng(s.seed);
  auto out = std::make_shared<Cloud>();
  const float slope = (r_top - r_bottom) / height;
  // Inside points are seen when their ray to the camera leaves through the opening.
  auto throughOpening = [&](const Eigen::Vector3f& p) {
    if (s.camera.z() <= height) return false;
    const Eigen::Vector3f q = p + (height - p.z()) / (s.camera.z() - p.z()) * (s.camera - p);
    return (q.head<2>() - centre).norm() < r_top - wall;
  };
  for (float z = 0.0f; z <= height + 1e-6f; z += s.spacing) {
    for (bool inside : {false, true}) {
      const float r = r_bottom + slope * z - (inside ? wall : 0.0f);
      if (inside && z < wall) continue;
      const int steps = std::max(8, static_cast<int>(2 * kPi * r / s.spacing));
      for (int i = 0; i < steps; ++i) {
        const float t = static_cast<float>(2 * kPi * i / steps);
        const Eigen::Vector3f p(centre.x() + r * std::cos(t), centre.y() + r * std::sin(t), z);
        Eigen::Vector3f n = Eigen::Vector3f(std::cos(t), std::sin(t), -slope).normalized();
        if (inside) {
          if (!throughOpening(p)) continue;
          n = -n;
        }
        addIfVisible(p, n, s, rng, *out);
      }
    }
  }
  for (float rr = 0.0f; rr <= r_bottom - wall; rr += s.spacing) {  // the floor inside
    const int steps = std::max(1, static_cast<int>(2 * kPi * rr / s.spacing));
    for (int i = 0; i < steps; ++i) {
      const float t = static_cast<float>(2 * kPi * i / steps);
      const Eigen::Vector3f p(centre.x() + rr * std::cos(t), centre.y() + rr * std::sin(t), wall);
      if (throughOpening(p)) addIfVisible(p, Eigen::Vector3f::UnitZ(), s, rng, *out);
    }
  }
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  return out;
}

// A cylinder (a can) lying on its side: axis horizontal at `yaw` about z, through (cx, cy, r).
// Side wall and both end discs.
inline CloudPtr lyingCylinder(float radius, float length, const Eigen::Vector2f& centre, float yaw,
                              const Sampler& s) {
  std::mt19937 rng(s.seed);
  auto out = std::make_shared<Cloud>();
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Eigen::Vector3f c(centre.x(), centre.y(), radius);
  const int steps = std::max(8, static_cast<int>(2 * kPi * radius / s.spacing));
  for (int i = 0; i < steps; ++i) {
    const float t = static_cast<float>(2 * kPi * i / steps);
    const Eigen::Vector3f n(0.0f, std::cos(t), std::sin(t));  // axis along local x
    for (float a = -length / 2; a <= length / 2 + 1e-6f; a += s.spacing) {
      addIfVisible(c + R * (Eigen::Vector3f(a, 0.0f, 0.0f) + radius * n), R * n, s, rng, *out);
    }
  }
  for (float sign : {-1.0f, 1.0f}) {
    for (float rr = 0.0f; rr <= radius; rr += s.spacing) {
      const int ring = std::max(1, static_cast<int>(2 * kPi * rr / s.spacing));
      for (int i = 0; i < ring; ++i) {
        const float t = static_cast<float>(2 * kPi * i / ring);
        const Eigen::Vector3f local(sign * length / 2, rr * std::cos(t), rr * std::sin(t));
        addIfVisible(c + R * local, R * Eigen::Vector3f(sign, 0.0f, 0.0f), s, rng, *out);
      }
    }
  }
  out->width = static_cast<uint32_t>(out->size());
  out->height = 1;
  return out;
}

// Lifts a table-frame object by `dz` (stacked on something of that height).
inline CloudPtr lifted(const CloudPtr& cloud, float dz) {
  auto out = std::make_shared<Cloud>(*cloud);
  for (auto& p : out->points) p.z += dz;
  return out;
}

// Points of `cloud` not covered by a footprint [x0, x1] x [y0, y1] at height z (the lower
// object's top under a stacked one).
inline CloudPtr withoutFootprint(const CloudPtr& cloud, float x0, float x1, float y0, float y1,
                                 float z) {
  auto out = std::make_shared<Cloud>();
  for (const auto& p : *cloud) {
    const bool covered = p.x > x0 && p.x < x1 && p.y > y0 && p.y < y1 && p.z > z - 0.002f;
    if (!covered) out->push_back(p);
  }
  return out;
}

// A camera optical frame (z forward, x right, y down) at `camera` looking at `target`; returns
// the table -> camera transform, so that the camera sits at the origin as in real clouds.
inline Eigen::Isometry3f tableToCamera(const Eigen::Vector3f& camera,
                                       const Eigen::Vector3f& target) {
  const Eigen::Vector3f forward = (target - camera).normalized();
  const Eigen::Vector3f right = forward.cross(Eigen::Vector3f::UnitZ()).normalized();
  const Eigen::Vector3f down = forward.cross(right);
  Eigen::Matrix3f camera_axes;  // columns: camera x, y, z in the table frame
  camera_axes << right, down, forward;
  Eigen::Isometry3f camera_pose = Eigen::Isometry3f::Identity();
  camera_pose.linear() = camera_axes;
  camera_pose.translation() = camera;
  return camera_pose.inverse();
}

// The camera frame of a sampler's camera looking at the table frame's origin.
inline Eigen::Isometry3f cameraFromTable(const Sampler& s) {
  return tableToCamera(s.camera, Eigen::Vector3f::Zero());
}

// The table plane z = 0 (normal up) in the table frame.
inline Plane tablePlane() { return Plane{Eigen::Vector3f::UnitZ(), 0.0f}; }

// Moves a table-frame cloud / plane into a camera-like frame by a rigid transform, so tests
// also exercise an arbitrary "up".
inline void transformCloud(const Eigen::Isometry3f& T, Cloud& cloud) {
  for (auto& p : cloud.points) p.getVector3fMap() = T * p.getVector3fMap();
}
inline Plane transformPlane(const Eigen::Isometry3f& T, const Plane& plane) {
  Plane out;
  out.normal = T.linear() * plane.normal;
  out.d = plane.d - out.normal.dot(T.translation());
  return out;
}

}  // namespace synthetic
}  // namespace tabletop_shapes
