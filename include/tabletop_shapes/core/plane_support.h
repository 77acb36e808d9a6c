// Plane inlier tests for the box fit's RANSAC (§3.2): hundreds of planes are tested against the
// same points, so the points are held one array per coordinate, in blocks of four that GCC's
// vector extension tests at once. Each lane does the same float operations as Eigen's dot of
// two 3-vectors (x0 y0 + (x1 y1 + x2 y2)), in the same order: the same results, to the bit, as
// the plain loop.
#pragma once

#include "tabletop_shapes/core/float4.h"
#include "tabletop_shapes/core/normals.h"

#include <vector>

namespace tabletop_shapes {

// Three coordinates of points in blocks of four; the padding of the last block lies far from
// every plane through the data, with a zero vector where the vectors are normals.
struct VectorBlocks {
  std::vector<Float4> x, y, z;
  void resize(size_t points, float padding);
  void set(size_t k, float px, float py, float pz) {
    x[k / 4][k % 4] = px;
    y[k / 4][k % 4] = py;
    z[k / 4][k % 4] = pz;
  }
};

// acos of four floats at once, for lanes in [0.5, 1) (the cosines of angles below 60 degrees):
// glibc's acosf algorithm for that range (fdlibm's, float operations in the same order), so the
// same floats as std::acos; the test compares every float of the range. Other lanes: undefined.
Float4 acosOfHalfToOne(Float4 x);

// The box fit's plane inliers among the points `indices` of a cloud with normals.
class PlaneSupport {
 public:
  PlaneSupport(const NormalCloud& cloud, const std::vector<int>& indices);

  // Number of inliers of the plane normal . p + d = 0: distance below `distance_threshold` AND
  // point normal within acos(`cos_threshold`) of the plane normal (either sign). `support`, when
  // given, receives their indices into the cloud (in the order given); `angle_sum`, when given
  // and at least `min_count` are found, gets the sum of the angles between their normals and the
  // plane's added. The same numbers, to the bit, as the plain loop over the points
  // (normal.dot(p) + d, |normal.dot(point normal)|, acos) summing into a zero `angle_sum`.
  int collect(const Eigen::Vector3f& normal, float d, float distance_threshold, float cos_threshold,
              std::vector<int>* support, double* angle_sum, int min_count = 0);

  // The number of inliers, as collect gives it, and in `angle_bound` a lower bound of the sum of
  // their angles that collect's `angle_sum` would give: acos(c) >= sqrt(2 (1 - c)) (acos(c) = 2
  // asin(x) >= 2 x, x = sqrt((1 - c) / 2)), less a margin for the floats' rounding. Within
  // x^2 / 6 of the sum (0.2 % at 10 degrees), for a root instead of an acos per point, so that
  // a ranking by mean angle needs the exact sums of the few planes that can come first.
  int countWithAngleBound(const Eigen::Vector3f& normal, float d, float distance_threshold,
                          float cos_threshold, double& angle_bound);

 private:
  static constexpr float kFarAway = 1e30f;
  struct PlaneTest;
  // The sum of the last plane's inliers' angles (collect's `angle_sum`).
  double sumOfInlierAngles() const;
  std::vector<int> indices_;
  VectorBlocks points_, normals_;
  // Per block, of the last plane: which points are inliers (bit i: lane i) and their |cosine|.
  std::vector<unsigned> inlier_lanes_;
  std::vector<Float4> cosine_;
};

// The inliers of planes among the points `indices` of a cloud (the table stage refines each
// plane it finds 4-6 times over the same 50-100k points): |normal . p + d| <= threshold, four
// points at a time, each lane with the float operations of Plane::signedDistance, so the points
// the plain loop finds, in the order given.
class PointsNearPlane {
 public:
  PointsNearPlane(const Cloud& cloud, const std::vector<int>& indices);
  void collect(const Plane& plane, float threshold, std::vector<int>& within) const;

 private:
  std::vector<int> indices_;
  VectorBlocks points_;
};

}  // namespace tabletop_shapes
