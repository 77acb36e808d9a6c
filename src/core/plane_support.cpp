#include "tabletop_shapes/core/plane_support.h"

#include "tabletop_shapes/core/cpu_features.h"
#include "tabletop_shapes/core/float8.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace tabletop_shapes {
namespace {

// The integer lanes (comparison masks) of as many lanes as Floats.
template <typename Floats>
struct IntLanesOf;
template <>
struct IntLanesOf<Float4> {
  using Type = Int4;
};

// The inlier test of a plane on a lane's worth of points at a time (Float4, or eight floats where
// the CPU has AVX2): distance below the threshold AND |cosine| of the point normal above the
// threshold. Each lane does the float operations of the scalar test, so any width gives the same
// inliers.

template <typename Floats>
struct LanePlaneTest {
  using Ints = typename IntLanesOf<Floats>::Type;
  // Always inlined: the eight-lane test runs inside an AVX2 function.
  [[gnu::always_inline]] static Floats all(float value) { return Floats{} + value; }
  [[gnu::always_inline]] static Floats magnitudeOf(Floats value) {
    return (Floats)((Ints)value & 0x7fffffff);
  }

  [[gnu::always_inline]] LanePlaneTest(const Eigen::Vector3f& normal, float d,
                                       float distance_threshold, float cos_threshold)
      : a(all(normal.x())),
        b(all(normal.y())),
        c(all(normal.z())),
        offset(all(d)),
        max_distance(all(distance_threshold)),
        min_cosine(all(cos_threshold)) {}
  // The lanes that are inliers (all bits set) and their |cosines| (`cosine`).
  [[gnu::always_inline]] Ints inliers(Floats x, Floats y, Floats z, Floats nx, Floats ny, Floats nz,
                                      Floats& cosine) const {
    const Floats distance = magnitudeOf((a * x + (b * y + c * z)) + offset);
    cosine = magnitudeOf(a * nx + (b * ny + c * nz));
    // Negated like `if (distance >= threshold) skip`, so that NaN passes alike.
    return ~(distance >= max_distance) & ~(cosine <= min_cosine);
  }
  Floats a, b, c, offset, max_distance, min_cosine;
};

// The lane operations countInLanes takes from its width: the square root, and
// min(1, cosine) with a NaN kept (1 < cosine ? 1 : cosine).
struct RootOfFour {
  static Float4 of(Float4 value) { return squareRoot(value); }
  static Float4 minOfOneAnd(Float4 cosine) {
    const Float4 one = broadcast(1.0f);
    return one < cosine ? one : cosine;
  }
};

// The columns countInLanes reads: `floats` values each, a multiple of every lane width.
struct PointColumns {
  const float *x, *y, *z, *normal_x, *normal_y, *normal_z;
  size_t floats;
};

template <typename Floats>
[[gnu::always_inline]] inline Floats loadFloats(const float* values) {
  Floats lanes;
  std::memcpy(&lanes, values, sizeof lanes);
  return lanes;
}

// PlaneSupport::countWithAngleBound on Floats lanes, the square root from Root::of: the inlier
// count, and in `bound_sum` the sum of the inliers' sqrt(2 (1 - cosine)), each lane summed in
// floats, the lanes in doubles.
template <typename Floats, typename Root>
[[gnu::always_inline]] inline int countInLanes(const PointColumns& columns,
                                               const LanePlaneTest<Floats>& test,
                                               double& bound_sum) {
  using Ints = typename LanePlaneTest<Floats>::Ints;
  constexpr size_t kLanes = sizeof(Floats) / sizeof(float);
  const Floats one = Floats{} + 1.0f;
  // Minus the number of outliers per lane (a mask of all bits set is -1): one instruction less
  // per step than counting the inliers, whose mask is the outliers' complement.
  Ints outliers = {};
  Floats bounds = {};
  // Two steps per turn, each adding to the same lanes in the same order.
#pragma GCC unroll 2
  for (size_t k = 0; k < columns.floats; k += kLanes) {
    Floats cosine;
    const Ints outlier = ~test.inliers(
        loadFloats<Floats>(columns.x + k), loadFloats<Floats>(columns.y + k),
        loadFloats<Floats>(columns.z + k), loadFloats<Floats>(columns.normal_x + k),
        loadFloats<Floats>(columns.normal_y + k), loadFloats<Floats>(columns.normal_z + k), cosine);
    outliers += outlier;
    // 1 - c is exact for c in [0.5, 1] (the inliers' cosines; a NaN stays NaN).
    const Floats clamped = Root::minOfOneAnd(cosine);
    bounds += (Floats)((Ints)Root::of((one - clamped) * 2.0f) & ~outlier);
  }
  // The lanes in pairs, in doubles.
  double sums[kLanes];
  for (size_t lane = 0; lane < kLanes; ++lane) sums[lane] = static_cast<double>(bounds[lane]);
  for (size_t width = kLanes / 2; width > 0; width /= 2) {
    for (size_t lane = 0; lane < width; ++lane) sums[lane] = sums[2 * lane] + sums[2 * lane + 1];
  }
  bound_sum = sums[0];
  int count = static_cast<int>(columns.floats);
  for (size_t lane = 0; lane < kLanes; ++lane) count += outliers[lane];
  return count;
}

#ifdef TABLETOP_SHAPES_EIGHT_LANES
template <>
struct IntLanesOf<Float8> {
  using Type = Int8;
};
struct RootOfEight {
  __attribute__((target("avx2"))) static Float8 of(Float8 value) { return squareRoot(value); }
  // vminps(a, b) is a < b ? a : b, the second operand where either is NaN: one instruction
  // where GCC makes the conditional a comparison and a blend.
  __attribute__((target("avx2"))) static Float8 minOfOneAnd(Float8 cosine) {
    return (Float8)_mm256_min_ps(_mm256_set1_ps(1.0f), (__m256)cosine);
  }
};

// countInLanes eight points at a time: about half the instructions of four at a time.
__attribute__((target("avx2"))) int countInEightLanes(const PointColumns& columns,
                                                      const Eigen::Vector3f& normal, float d,
                                                      float distance_threshold, float cos_threshold,
                                                      double& bound_sum) {
  const LanePlaneTest<Float8> test(normal, d, distance_threshold, cos_threshold);
  return countInLanes<Float8, RootOfEight>(columns, test, bound_sum);
}
#endif

bool hasEightLanes() {
#ifdef TABLETOP_SHAPES_EIGHT_LANES
  return cpuHasAvx2();
#else
  return false;
#endif
}

}  // namespace

Float4 acosOfHalfToOne(Float4 x) {
  // fdlibm's e_acosf.c, branch x >= 0.5: acos(x) = 2 asin(sqrt((1 - x) / 2)), the asin from a
  // rational approximation and a split of the root into a high part and a correction.
  constexpr float kP0 = 1.6666667163e-01f, kP1 = -3.2556581497e-01f, kP2 = 2.0121252537e-01f,
                  kP3 = -4.0055535734e-02f, kP4 = 7.9153501429e-04f, kP5 = 3.4793309169e-05f;
  constexpr float kQ1 = -2.4033949375e+00f, kQ2 = 2.0209457874e+00f, kQ3 = -6.8828397989e-01f,
                  kQ4 = 7.7038154006e-02f;
  const Float4 z = (1.0f - x) * 0.5f;
  const Float4 s = squareRoot(z);
  const Float4 high = (Float4)((Int4)s & static_cast<int>(0xfffff000u));
  const Float4 correction = (z - high * high) / (s + high);
  const Float4 p = z * (kP0 + z * (kP1 + z * (kP2 + z * (kP3 + z * (kP4 + z * kP5)))));
  const Float4 q = 1.0f + z * (kQ1 + z * (kQ2 + z * (kQ3 + z * kQ4)));
  const Float4 w = (p / q) * s + correction;
  return 2.0f * (high + w);
}

void VectorBlocks::resize(size_t points, float padding) {
  const size_t blocks = (points + 3) / 4;
  for (auto* column : {&x, &y, &z}) column->assign(blocks, broadcast(padding));
}

PlaneSupport::PlaneSupport(const NormalCloud& cloud, const std::vector<int>& indices)
    : indices_(indices) {
  // Padded to a multiple of eight points (an even number of blocks), for countInEightLanes.
  const size_t padded = (indices.size() + 7) / 8 * 8;
  points_.resize(padded, kFarAway);
  normals_.resize(padded, 0.0f);
  for (size_t k = 0; k < indices.size(); ++k) {
    const auto& p = cloud[indices[k]];
    points_.set(k, p.x, p.y, p.z);
    normals_.set(k, p.normal_x, p.normal_y, p.normal_z);
  }
  inlier_lanes_.resize(points_.x.size());
  cosine_.resize(points_.x.size());
}

struct PlaneSupport::PlaneTest : LanePlaneTest<Float4> {
  using LanePlaneTest<Float4>::LanePlaneTest;
  // The lanes of block k that are inliers (all bits set) and its |cosines| (`cosine`).
  Int4 inliers(const PlaneSupport& points, size_t k, Float4& cosine) const {
    return LanePlaneTest<Float4>::inliers(points.points_.x[k], points.points_.y[k],
                                          points.points_.z[k], points.normals_.x[k],
                                          points.normals_.y[k], points.normals_.z[k], cosine);
  }
};

int PlaneSupport::collect(const Eigen::Vector3f& normal, float d, float distance_threshold,
                          float cos_threshold, std::vector<int>* support, double* angle_sum,
                          int min_count) {
  const PlaneTest test(normal, d, distance_threshold, cos_threshold);
  Int4 counts = {};
  for (size_t k = 0; k < points_.x.size(); ++k) {
    const Int4 inlier = test.inliers(*this, k, cosine_[k]);
    inlier_lanes_[k] = lanesOf(inlier);
    counts -= inlier;
  }
  const int count = counts[0] + counts[1] + counts[2] + counts[3];
  if (support) {
    for (size_t k = 0; k < inlier_lanes_.size(); ++k) {
      for (unsigned lanes = inlier_lanes_[k]; lanes != 0; lanes &= lanes - 1) {
        support->push_back(indices_[4 * k + __builtin_ctz(lanes)]);
      }
    }
  }
  if (angle_sum && count >= min_count) *angle_sum += sumOfInlierAngles();
  return count;
}

int PlaneSupport::countWithAngleBound(const Eigen::Vector3f& normal, float d,
                                      float distance_threshold, float cos_threshold,
                                      double& angle_bound) {
  // data(), not front(): a PlaneSupport of no points has empty blocks.
  const auto floats = [](const std::vector<Float4>& blocks) {
    return reinterpret_cast<const float*>(blocks.data());
  };
  const PointColumns columns{floats(points_.x),   floats(points_.y),  floats(points_.z),
                             floats(normals_.x),  floats(normals_.y), floats(normals_.z),
                             4 * points_.x.size()};
  double bound_sum = 0.0;
  int count = 0;
#ifdef TABLETOP_SHAPES_EIGHT_LANES
  if (hasEightLanes()) {
    count = countInEightLanes(columns, normal, d, distance_threshold, cos_threshold, bound_sum);
  } else
#endif
  {
    const PlaneTest test(normal, d, distance_threshold, cos_threshold);
    count = countInLanes<Float4, RootOfFour>(columns, test, bound_sum);
  }
  // Each root within half an ulp, acosf within one, the lanes' float sums within one ulp per
  // term: a relative margin of 2^-22 per block of four and a few more keeps the bound below the
  // sum (a lane of eight sums half as many terms).
  const double margin = 1.0 - std::ldexp(static_cast<double>(points_.x.size() + 4), -22);
  angle_bound = margin * bound_sum;
  return count;
}

double PlaneSupport::sumOfInlierAngles() const {
  // Each angle is a float: 0 or at least acos(1 - 2^-24) > 2^-12, so a multiple of 2^-35, and
  // at most pi < 4. Their sum is exact in a double (53 bits) below 2^18, i.e. for up to 2^16
  // points, and then the same in any order; beyond, it is summed in the points' order.
  const bool exact_in_any_order = 4 * inlier_lanes_.size() <= (1u << 16);
  const Float4 one = broadcast(1.0f), half = broadcast(0.5f);
  const Int4 lane_bits = {1, 2, 4, 8};
  Double2 low_lanes = {}, high_lanes = {};
  double sum = 0.0;
  for (size_t k = 0; k < inlier_lanes_.size(); ++k) {
    const unsigned lanes = inlier_lanes_[k];
    if (lanes == 0) continue;
    // std::min(cosine, 1.0f) per lane (NaN stays NaN), and the acos of all four at once where
    // they lie in [0.5, 1); acos(1) = 0 and the rare others one at a time.
    const Float4 cosine = one < cosine_[k] ? one : cosine_[k];
    const Float4 angle = acosOfHalfToOne(cosine);
    if (exact_in_any_order) {
      const Int4 inlier = ((Int4{} + static_cast<int>(lanes)) & lane_bits) != 0;
      const Int4 vector_lanes = inlier & (cosine >= half) & (cosine < one);
      const Float4 kept = (Float4)((Int4)angle & vector_lanes);
      low_lanes += Double2{kept[0], kept[1]};
      high_lanes += Double2{kept[2], kept[3]};
      for (unsigned rest = lanes & ~lanesOf(vector_lanes); rest != 0; rest &= rest - 1) {
        sum += std::acos(cosine[__builtin_ctz(rest)]);  // 0 for a cosine of 1
      }
      continue;
    }
    for (unsigned rest = lanes; rest != 0; rest &= rest - 1) {
      const float c = cosine[__builtin_ctz(rest)];
      sum += c >= 0.5f && c < 1.0f ? angle[__builtin_ctz(rest)] : std::acos(c);
    }
  }
  return sum + ((low_lanes[0] + low_lanes[1]) + (high_lanes[0] + high_lanes[1]));
}

PointsNearPlane::PointsNearPlane(const Cloud& cloud, const std::vector<int>& indices)
    : indices_(indices) {
  points_.resize(indices.size(), std::numeric_limits<float>::quiet_NaN());  // never within
  for (size_t k = 0; k < indices.size(); ++k) {
    const Point& p = cloud[indices[k]];
    points_.set(k, p.x, p.y, p.z);
  }
  indices_.resize(4 * points_.x.size(), -1);  // the padding's, never collected
}

void PointsNearPlane::collect(const Plane& plane, float threshold, std::vector<int>& within) const {
  const Float4 a = broadcast(plane.normal.x()), b = broadcast(plane.normal.y()),
               c = broadcast(plane.normal.z()), offset = broadcast(plane.d);
  const Float4 max_distance = broadcast(threshold);
  // Written into a buffer kept from call to call (no clearing), without a branch per point:
  // every index of a partly kept block is written, the count advanced past the kept ones.
  thread_local std::vector<int> kept;
  if (kept.size() < indices_.size()) kept.resize(indices_.size());
  int* out = kept.data();
  const int* index = indices_.data();
  size_t count = 0;
  for (size_t k = 0; k < points_.x.size(); ++k, index += 4) {
    const Float4 distance = (a * points_.x[k] + (b * points_.y[k] + c * points_.z[k])) + offset;
    const unsigned lanes = lanesOf(magnitude(distance) <= max_distance);
    if (lanes == 0) continue;
    if (lanes == 15) {  // runs of whole blocks on a plane's surface
      std::memcpy(out + count, index, 4 * sizeof(int));
      count += 4;
      continue;
    }
    for (int lane = 0; lane < 4; ++lane) {
      out[count] = index[lane];
      count += (lanes >> lane) & 1u;
    }
  }
  within.assign(out, out + count);
}

}  // namespace tabletop_shapes
