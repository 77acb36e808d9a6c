#include "tabletop_shapes/core/normals.h"

#include "tabletop_shapes/core/cpu_features.h"
#include "tabletop_shapes/core/exp_lanes.h"
#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/parallel.h"

#include <pcl/common/eigen.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define TABLETOP_SHAPES_GATHER_LANES 1
#endif

namespace tabletop_shapes {
namespace {

// The passes below run on 32 bytes of neighbours at a time, one per lane (GCC's vector
// extension: one AVX instruction where fitLocalSurface's AVX2 clone runs, two SSE2 ones
// elsewhere, the same numbers either way, as no clone fuses a multiply and an add): eight
// floats or four doubles. Floats suffice where every quantity summed is small and of one
// scale: the offsets from the query point (exact in floats where the two coordinates lie
// within a factor 2 of each other, else rounded below 1e-9 m) for the plane, and for a polynomial
// of order 2 the Darboux coordinates in units of the search radius (|u|, |v| <= ~1.5), whose
// moments up to degree 4 are of order 1 (against PCL's doubles: points within 1e-6 m, normals
// within 1e-5). Orders 3 and 4 stay in doubles: their normal equations are too ill-conditioned for
// float sums (normals off by up to 0.1). The sums of the lanes, the plane's eigenvectors and the
// normal equations' solution are doubles.
constexpr size_t kLaneBytes = 32;
// The helpers below are always inlined: no call passes lanes by value, so GCC's note that
// doing so without AVX changes the ABI does not apply.
#pragma GCC diagnostic ignored "-Wpsabi"
template <typename Real>
struct LaneTypes;
template <>
struct LaneTypes<float> {
  using Lanes = float __attribute__((vector_size(kLaneBytes)));
  using Floats = Lanes;  // the coordinates of as many neighbours
};
template <>
struct LaneTypes<double> {
  using Lanes = double __attribute__((vector_size(kLaneBytes)));
  using Floats = float __attribute__((vector_size(kLaneBytes / 2)));
};
template <typename Real>
using LanesOf = typename LaneTypes<Real>::Lanes;
template <typename Real>
constexpr size_t kLanesOf = kLaneBytes / sizeof(Real);
constexpr size_t kMostLanes = kLanesOf<float>;  // neighbourhoods are padded to a multiple
using FloatLanes = LanesOf<float>;
using IntLanes = int32_t __attribute__((vector_size(kLaneBytes)));

template <typename Real>
[[gnu::always_inline]] inline LanesOf<Real> loadLanes(const Real* values) {
  LanesOf<Real> lanes;
  std::memcpy(&lanes, values, sizeof lanes);
  return lanes;
}

template <typename Real>
[[gnu::always_inline]] inline void storeLanes(Real* values, LanesOf<Real> lanes) {
  std::memcpy(values, &lanes, sizeof lanes);
}

// The lanes of a float vector in doubles, each added to the one four places on (exact). Written
// lane by lane, which GCC 12 makes two 4-lane conversions and an add in the AVX2 clone; its
// __builtin_convertvector of the two halves took 13 instructions (2-lane conversions and inserts).
[[gnu::always_inline]] inline LanesOf<double> foldedInDoubles(FloatLanes l) {
  return LanesOf<double>{double{l[0]} + double{l[4]}, double{l[1]} + double{l[5]},
                         double{l[2]} + double{l[6]}, double{l[3]} + double{l[7]}};
}
[[gnu::always_inline]] inline LanesOf<double> foldedInDoubles(LanesOf<double> lanes) {
  return lanes;
}

// sums[i] = the sum of the lanes of lanes[i], i < kCount, in doubles: (l0 + l1) + (l2 + l3) of
// the lanes in doubles, four vectors at a time, each step one add for the four after a shuffle.
template <int kCount, typename Lanes>
[[gnu::always_inline]] inline void sumsOfLanes(const Lanes (&lanes)[kCount], double* sums) {
  using Doubles = LanesOf<double>;
  constexpr int kGroups = (kCount + 3) / 4;
  Doubles folded[4 * kGroups] = {};
#pragma GCC unroll 28
  for (int i = 0; i < kCount; ++i) folded[i] = foldedInDoubles(lanes[i]);
#pragma GCC unroll 7
  for (int group = 0; group < kGroups; ++group) {
    const Doubles a = folded[4 * group], b = folded[4 * group + 1], c = folded[4 * group + 2],
                  d = folded[4 * group + 3];
    // (a0 + a1, b0 + b1, a2 + a3, b2 + b3), the same of c and d, then their halves added.
    const Doubles ab =
        __builtin_shufflevector(a, b, 0, 4, 2, 6) + __builtin_shufflevector(a, b, 1, 5, 3, 7);
    const Doubles cd =
        __builtin_shufflevector(c, d, 0, 4, 2, 6) + __builtin_shufflevector(c, d, 1, 5, 3, 7);
    const Doubles totals =
        __builtin_shufflevector(ab, cd, 0, 1, 4, 5) + __builtin_shufflevector(ab, cd, 2, 3, 6, 7);
#pragma GCC unroll 4
    for (int i = 0; i < 4; ++i) {
      if (4 * group + i < kCount) sums[4 * group + i] = totals[i];
    }
  }
}

// exp of each lane (Cephes' expf: exp(x) = 2^k exp(f), k = round(x / ln 2), |f| <= ln 2 / 2,
// exp(f) by a polynomial of degree 7) for x in [-87, 88], where Cephes clamps it (a NaN stays
// NaN): within 1 float ulp of exp on MLS's weights' range (measured on every float of [-5, 0]
// and on [-87, -5] in steps of 1e-4). MLS's exponents -d^2 / r^2 lie in [-4, 0] (a neighbour
// and the frame's origin each within the radius of the query point), so the clamp, two
// comparisons and two blends per lane's worth, is left out.
[[gnu::always_inline]] inline FloatLanes expLanes(FloatLanes x) {
  constexpr float kRound = 12582912.0f;  // 1.5 * 2^23: adding it rounds to an integer
  const FloatLanes k = (x * 1.44269504088896341f + kRound) - kRound;
  const FloatLanes f = (x - k * 0.693359375f) - k * -2.12194440e-4f;
  FloatLanes p = FloatLanes{} + 1.9875691500e-4f;
  p = p * f + 1.3981999507e-3f;
  p = p * f + 8.3334519073e-3f;
  p = p * f + 4.1665795894e-2f;
  p = p * f + 1.6666665459e-1f;
  p = p * f + 5.0000001201e-1f;
  p = (p * f) * f + f + 1.0f;
  const IntLanes exponent = (__builtin_convertvector(k, IntLanes) + 127) << 23;
  FloatLanes scale;
  std::memcpy(&scale, &exponent, sizeof scale);
  return p * scale;
}

constexpr int kMaxOrder = 4;  // normals.polynomial_order's range

// Neighbours in the Darboux frame: u, v and height in units of the search radius, and their
// weights, one array per quantity.
template <typename Real>
struct FrameCoordinates {
  std::vector<Real> u, v, height, weight;
  void resize(size_t size) {
    for (std::vector<Real>* values : {&u, &v, &height, &weight}) values->resize(size);
  }
};

#ifdef TABLETOP_SHAPES_GATHER_LANES
// xs[k], ys[k], zs[k] = the coordinates of cloud[indices[k]], eight neighbours at a time with
// AVX2's gathers (three instructions for eight neighbours' coordinates, against ~80 one at a
// time) where the CPU has them; the number of neighbours copied (a multiple of 8).
__attribute__((target("avx2"))) size_t gatherEightAtATimeInAvx2(const Cloud& cloud,
                                                                const pcl::Indices& indices,
                                                                float* xs, float* ys, float* zs) {
  static_assert(sizeof(Point) == 4 * sizeof(float) && sizeof(pcl::index_t) == sizeof(int32_t));
  const float* first = &cloud.points.front().x;
  size_t k = 0;
  for (; k + 8 <= indices.size(); k += 8) {
    // The offset of each point's x in floats (the cloud holds far fewer than 2^29 points).
    const __m256i at =
        _mm256_slli_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(&indices[k])), 2);
    _mm256_storeu_ps(xs + k, _mm256_i32gather_ps(first, at, sizeof(float)));
    _mm256_storeu_ps(ys + k, _mm256_i32gather_ps(first + 1, at, sizeof(float)));
    _mm256_storeu_ps(zs + k, _mm256_i32gather_ps(first + 2, at, sizeof(float)));
  }
  return k;
}
#endif

// As many neighbours' coordinates as gatherEightAtATimeInAvx2 copies where the CPU has AVX2,
// else none; their number.
size_t gatherEightAtATime(const Cloud& cloud, const pcl::Indices& indices, float* xs, float* ys,
                          float* zs) {
#ifdef TABLETOP_SHAPES_GATHER_LANES
  if (cpuHasAvx2()) return gatherEightAtATimeInAvx2(cloud, indices, xs, ys, zs);
#endif
  return 0;
}

// A neighbourhood as the passes of fitLocalSurface read it, one array per quantity, padded to
// a multiple of kMostLanes so that each pass runs on whole lanes: first the neighbours'
// coordinates as the cloud holds them (their offsets from the query point are taken in the
// passes), then, for a polynomial fitted in doubles, their place in the Darboux frame. The
// padding neighbours sit at the query point and weigh 0, so they add exact zeros to every sum.
struct Neighbourhood {
  std::vector<float> px, py, pz;
  FrameCoordinates<double> frame_in_doubles;  // for orders 3 and 4
  Eigen::Vector3f query;
  size_t count = 0, padded = 0;

  void gather(const Cloud& cloud, const pcl::Indices& indices, const Point& query_point) {
    count = indices.size();
    padded = (count + kMostLanes - 1) / kMostLanes * kMostLanes;
    query = query_point.getVector3fMap();
    if (px.size() < padded) {  // grown only: the passes read the first `padded`
      for (std::vector<float>* values : {&px, &py, &pz}) values->resize(padded);
    }
    float *xs = px.data(), *ys = py.data(), *zs = pz.data();
    for (size_t k = gatherEightAtATime(cloud, indices, xs, ys, zs); k < count; ++k) {
      const Point& p = cloud[indices[k]];
      xs[k] = p.x, ys[k] = p.y, zs[k] = p.z;
    }
    for (size_t k = count; k < padded; ++k)
      xs[k] = query_point.x, ys[k] = query_point.y, zs[k] = query_point.z;
  }
};

// The calling thread's Neighbourhood (MLS runs on several threads), reused from point to point.
// Out of line: where the thread_local was named in the caller, GCC took its address again
// (__tls_get_addr, about 11 instructions) after each call and loop of the inlined gather, five
// times per point.
[[gnu::noinline]] Neighbourhood& threadNeighbourhood() {
  thread_local Neighbourhood near;
  return near;
}

// Neighbours k .. k + kLanesOf<Real> - 1 of `coordinates` less the query's `origin` (exact in
// floats), in Real.
template <typename Real>
[[gnu::always_inline]] inline LanesOf<Real> offsetLanes(const float* coordinates, size_t k,
                                                        float origin) {
  typename LaneTypes<Real>::Floats floats;
  std::memcpy(&floats, coordinates + k, sizeof floats);
  return __builtin_convertvector(floats - origin, LanesOf<Real>);
}

// The neighbours' centroid (as an offset from the query point) and scatter matrix about it
// (PCL's computeCovarianceMatrix: sums, not divided by the count), from the sums of the offsets
// and of their products in one pass: offsets within the search radius, so the difference of the
// two sums loses nothing that matters (float sums: ~1e-11 m^2 against a scatter of 1e-6 m^2 or
// more).
[[gnu::always_inline]] inline void centroidAndScatter(const Neighbourhood& near,
                                                      Eigen::Vector3d& centroid,
                                                      Eigen::Matrix3d& scatter) {
  FloatLanes sx = {}, sy = {}, sz = {}, sxx = {}, sxy = {}, sxz = {}, syy = {}, syz = {}, szz = {};
  const float *xs = near.px.data(), *ys = near.py.data(), *zs = near.pz.data();
  for (size_t k = 0, padded = near.padded; k < padded; k += kMostLanes) {
    const FloatLanes x = offsetLanes<float>(xs, k, near.query[0]),
                     y = offsetLanes<float>(ys, k, near.query[1]),
                     z = offsetLanes<float>(zs, k, near.query[2]);
    sx += x, sy += y, sz += z;
    sxx += x * x, sxy += x * y, sxz += x * z;
    syy += y * y, syz += y * z, szz += z * z;
  }
  const FloatLanes lanes[9] = {sx, sy, sz, sxx, sxy, sxz, syy, syz, szz};
  double sums[9];
  sumsOfLanes(lanes, sums);
  const Eigen::Vector3d first(sums[0], sums[1], sums[2]);
  Eigen::Matrix3d second;
  second << sums[3], sums[4], sums[5],  //
      sums[4], sums[6], sums[7],        //
      sums[5], sums[7], sums[8];
  const double count = static_cast<double>(near.count);
  centroid = first / count;
  scatter = second - first * centroid.transpose();
}

// Index of u^i v^j among the monomials of degree <= `degree` (i-major order, j fastest).
constexpr int monomialIndex(int i, int j, int degree) {
  return i * (degree + 1) - i * (i - 1) / 2 + j;
}

// MLS's polynomial of order kOrder in PCL's term order, u^i v^j with j fastest: its terms, and
// the moments of the weights sum(w u^i v^j), i + j <= 2 kOrder, in the same order, of which the
// normal equations are made (entry (a, b) is the moment of term a's exponents plus term b's).
template <int kOrder>
struct Polynomial {
  static constexpr int kTerms = (kOrder + 1) * (kOrder + 2) / 2;
  static constexpr int kDegree = 2 * kOrder;
  static constexpr int kMoments = (kDegree + 1) * (kDegree + 2) / 2;
  // The moment of normal-equation entry (a, b): that of term a's exponents plus term b's.
  static constexpr std::array<std::array<int, kTerms>, kTerms> kEntryMoment = [] {
    int exponents[kTerms][2] = {};
    for (int i = 0, term = 0; i <= kOrder; ++i) {
      for (int j = 0; j <= kOrder - i; ++j, ++term) exponents[term][0] = i, exponents[term][1] = j;
    }
    std::array<std::array<int, kTerms>, kTerms> moment_of{};
    for (int a = 0; a < kTerms; ++a) {
      for (int b = 0; b < kTerms; ++b) {
        moment_of[a][b] = monomialIndex(exponents[a][0] + exponents[b][0],
                                        exponents[a][1] + exponents[b][1], kDegree);
      }
    }
    return moment_of;
  }();
};

// One lane's worth of neighbours (one per lane) added to the moments of the weights
// sum(w u^i v^j), i + j <= 2 kOrder, and to the right-hand sums sum(w u^i v^j height),
// i + j <= kOrder, both in Polynomial<kOrder>'s order: each product w v^j u^i made of the
// weight times v j times, then u i times. Always inlined with the sums in the caller's locals,
// so that they stay in registers where they fit.
template <int kOrder, typename Lanes>
[[gnu::always_inline]] inline void addMoments(Lanes u, Lanes v, Lanes height, Lanes weight,
                                              Lanes (&moments)[Polynomial<kOrder>::kMoments],
                                              Lanes (&right)[Polynomial<kOrder>::kTerms]) {
  constexpr int kDegree = Polynomial<kOrder>::kDegree;
  Lanes row[kDegree + 1];  // w u^i v^j for j = 0 .. kDegree - i, i rising pass by pass
  row[0] = weight;
#pragma GCC unroll 8
  for (int j = 1; j <= kDegree; ++j) row[j] = row[j - 1] * v;
  int moment = 0, term = 0;
#pragma GCC unroll 9
  for (int i = 0; i <= kDegree; ++i) {
#pragma GCC unroll 9
    for (int j = 0; j <= kDegree - i; ++j) moments[moment++] += row[j];
    if (i <= kOrder) {
#pragma GCC unroll 5
      for (int j = 0; j <= kOrder - i; ++j) right[term++] += row[j] * height;
    }
#pragma GCC unroll 8
    for (int j = 0; j < kDegree - i; ++j) row[j] *= u;
  }
}

// The weighted least-squares polynomial of the heights over (u, v) (PCL's weight exp(-d^2 /
// r^2)) in `coefficients`, from the lanes of addMoments' sums: its normal equations, with the
// order fixed at compile time so that the loops unroll. False when the normal equations are not
// positive definite (neighbours on a line in (u, v)).
template <int kOrder, typename Lanes>
[[gnu::always_inline]] inline bool solvePolynomial(
    const Lanes (&moments)[Polynomial<kOrder>::kMoments],
    const Lanes (&right)[Polynomial<kOrder>::kTerms], double* coefficients) {
  using Poly = Polynomial<kOrder>;
  constexpr int kTerms = Poly::kTerms;
  double moment_sums[Poly::kMoments], right_sums[kTerms];
  sumsOfLanes(moments, moment_sums);
  sumsOfLanes(right, right_sums);
  Eigen::Matrix<double, kTerms, kTerms> normal_matrix;
  Eigen::Matrix<double, kTerms, 1> right_side;
#pragma GCC unroll 15
  for (int a = 0; a < kTerms; ++a) {
    right_side[a] = right_sums[a];
#pragma GCC unroll 15
    for (int b = 0; b <= a; ++b) normal_matrix(a, b) = moment_sums[Poly::kEntryMoment[a][b]];
  }
  // Cholesky of the lower triangle in place, then the two triangular solves: a fixed size the
  // compiler unrolls (Eigen's LLT runs its blocked loops for a 6 x 6 matrix), the inner loops
  // too (a pragma unrolls only the loop it stands before: they were loops of 1-5 turns).
  double* x = right_side.data();
#pragma GCC unroll 15
  for (int j = 0; j < kTerms; ++j) {
    double diagonal = normal_matrix(j, j);
#pragma GCC unroll 15
    for (int k = 0; k < j; ++k) diagonal -= normal_matrix(j, k) * normal_matrix(j, k);
    if (!(diagonal > 0.0)) return false;
    const double pivot = std::sqrt(diagonal);
    normal_matrix(j, j) = pivot;
#pragma GCC unroll 15
    for (int i = j + 1; i < kTerms; ++i) {
      double entry = normal_matrix(i, j);
#pragma GCC unroll 15
      for (int k = 0; k < j; ++k) entry -= normal_matrix(i, k) * normal_matrix(j, k);
      normal_matrix(i, j) = entry / pivot;
    }
  }
#pragma GCC unroll 15
  for (int i = 0; i < kTerms; ++i) {
#pragma GCC unroll 15
    for (int k = 0; k < i; ++k) x[i] -= normal_matrix(i, k) * x[k];
    x[i] /= normal_matrix(i, i);
  }
#pragma GCC unroll 15
  for (int i = kTerms - 1; i >= 0; --i) {
#pragma GCC unroll 15
    for (int k = i + 1; k < kTerms; ++k) x[i] -= normal_matrix(k, i) * x[k];
    x[i] /= normal_matrix(i, i);
  }
  for (int a = 0; a < kTerms; ++a) coefficients[a] = x[a];
  return true;
}

// The Darboux frame of a query point: its origin (the query point projected on the plane, as
// an offset from the query point; PCL's MLSResult::mean) and axes (the plane's normal last).
struct DarbouxFrame {
  Eigen::Vector3d origin, u_axis, v_axis, normal;
};

// Neighbours k .. k + kLanesOf<Real> - 1 of a Neighbourhood in a Darboux frame, in Real lanes: u,
// v and height in units of the search radius, and the exponent -d^2 / r^2 of their weights.
template <typename Real>
struct FrameLanes {
  LanesOf<Real> u, v, height, exponent;
};

template <typename Real>
struct InFrame {
  using Lanes = LanesOf<Real>;
  using Vector = Eigen::Matrix<Real, 3, 1>;
  InFrame(const Neighbourhood& near, const DarbouxFrame& darboux, double search_radius)
      : xs(near.px.data()),
        ys(near.py.data()),
        zs(near.pz.data()),
        query_x(near.query[0]),
        query_y(near.query[1]),
        query_z(near.query[2]),
        inverse_radius(static_cast<Real>(1.0 / search_radius)),
        at(darboux.origin.cast<Real>()),
        u_along(darboux.u_axis.cast<Real>()),
        v_along(darboux.v_axis.cast<Real>()),
        up(darboux.normal.cast<Real>()) {}

  [[gnu::always_inline]] FrameLanes<Real> lanes(size_t k) const {
    const Lanes x = (offsetLanes<Real>(xs, k, query_x) - at[0]) * inverse_radius;
    const Lanes y = (offsetLanes<Real>(ys, k, query_y) - at[1]) * inverse_radius;
    const Lanes z = (offsetLanes<Real>(zs, k, query_z) - at[2]) * inverse_radius;
    return {x * u_along[0] + y * u_along[1] + z * u_along[2],
            x * v_along[0] + y * v_along[1] + z * v_along[2], x * up[0] + y * up[1] + z * up[2],
            -(x * x + y * y + z * z)};
  }

  // The arrays and the query point in members of their own: read through the Neighbourhood they
  // were loaded again in each turn (the stores may alias anything).
  const float *xs, *ys, *zs;
  const float query_x, query_y, query_z;
  const Real inverse_radius;
  const Vector at, u_along, v_along, up;
};

// The neighbours' coordinates in `darboux` in units of the radius and their weights, then the
// polynomial of order kOrder fitted over them, in Real lanes. In floats (order 2) in one pass,
// each lane's weight from expLanes; in doubles the coordinates are stored first, for
// expInPlace's weights.
template <int kOrder, typename Real>
[[gnu::always_inline]] inline bool fitPolynomialInFrame(Neighbourhood& near,
                                                        const DarbouxFrame& darboux,
                                                        double search_radius,
                                                        double* coefficients) {
  using Lanes = LanesOf<Real>;
  using Poly = Polynomial<kOrder>;
  constexpr size_t kLanes = kLanesOf<Real>;
  const InFrame<Real> in_frame(near, darboux, search_radius);
  Lanes moments[Poly::kMoments] = {};
  Lanes right[Poly::kTerms] = {};
  if constexpr (std::is_same_v<Real, float>) {
    // The padding neighbours weigh 0 (all bits clear), in the last lanes only.
    const size_t count = near.count, whole = count / kLanes * kLanes;
    auto add = [&](size_t k, bool padded) __attribute__((always_inline)) {
      const FrameLanes<float> frame = in_frame.lanes(k);
      FloatLanes weight = expLanes(frame.exponent);
      if (padded) {
        const IntLanes lane = {0, 1, 2, 3, 4, 5, 6, 7};
        weight = (FloatLanes)((IntLanes)weight & (lane < static_cast<int>(count - k)));
      }
      addMoments<kOrder>(frame.u, frame.v, frame.height, weight, moments, right);
    };
    for (size_t k = 0; k < whole; k += kLanes) add(k, false);
    if (whole < near.padded) add(whole, true);
  } else {
    FrameCoordinates<Real>& frame = near.frame_in_doubles;
    if (frame.u.size() < near.padded) frame.resize(near.padded);  // grown only
    Real *weights = frame.weight.data(), *us = frame.u.data(), *vs = frame.v.data(),
         *heights = frame.height.data();
    for (size_t k = 0, padded = near.padded; k < padded; k += kLanes) {
      const FrameLanes<Real> lanes = in_frame.lanes(k);
      storeLanes(weights + k, lanes.exponent);
      storeLanes(us + k, lanes.u);
      storeLanes(vs + k, lanes.v);
      storeLanes(heights + k, lanes.height);
    }
    expInPlace(weights, near.padded);
    for (size_t k = near.count; k < near.padded; ++k) weights[k] = 0;
    for (size_t k = 0, padded = near.padded; k < padded; k += kLanes) {
      addMoments<kOrder>(loadLanes(us + k), loadLanes(vs + k), loadLanes(heights + k),
                         loadLanes(weights + k), moments, right);
    }
  }
  return solvePolynomial<kOrder>(moments, right, coefficients);
}

// The smallest eigenvalue of the symmetric positive semi-definite `scatter` and its unit
// eigenvector, as pcl::eigen33 gives them (the matrix scaled to entries in [-1, 1], the
// eigenvector from the cross products of the rows of the matrix less the eigenvalue) but for
// the eigenvalue: the smallest root of the characteristic polynomial by Newton's method (from 0
// the iterates rise monotonically to it, as the polynomial is increasing and concave below its
// smallest root; 5 steps for most points, at most 9 on 65k points of two OSD scenes and a
// rendered one) instead of the closed form's atan2, sin and cos. Where Newton is slow (a double
// root: points on a line or in a ball) or the root is 0, pcl::eigen33 itself.
void smallestEigenvector(const Eigen::Matrix3d& scatter, double& eigen_value,
                         Eigen::Vector3d& eigen_vector) {
  double scale = scatter.cwiseAbs().maxCoeff();
  if (scale <= std::numeric_limits<double>::min()) scale = 1.0;
  Eigen::Matrix3d m = scatter / scale;
  // x^3 - c2 x^2 + c1 x - c0, as pcl::computeRoots writes it.
  const double c0 = m(0, 0) * m(1, 1) * m(2, 2) + 2.0 * m(0, 1) * m(0, 2) * m(1, 2) -
                    m(0, 0) * m(1, 2) * m(1, 2) - m(1, 1) * m(0, 2) * m(0, 2) -
                    m(2, 2) * m(0, 1) * m(0, 1);
  const double c1 = m(0, 0) * m(1, 1) - m(0, 1) * m(0, 1) + m(0, 0) * m(2, 2) - m(0, 2) * m(0, 2) +
                    m(1, 1) * m(2, 2) - m(1, 2) * m(1, 2);
  const double c2 = m(0, 0) + m(1, 1) + m(2, 2);
  if (!(std::abs(c0) >= std::numeric_limits<double>::epsilon()))
    return pcl::eigen33(scatter, eigen_value, eigen_vector);  // a root 0 (PCL: quadratic)
  constexpr int kMaxNewtonSteps = 12;
  double root = 0.0;
  for (int steps = 0;; ++steps) {
    if (steps == kMaxNewtonSteps) return pcl::eigen33(scatter, eigen_value, eigen_vector);
    const double value = ((root - c2) * root + c1) * root - c0;
    const double slope = (3.0 * root - 2.0 * c2) * root + c1;
    const double rise = -value / slope;
    if (!std::isfinite(rise)) return pcl::eigen33(scatter, eigen_value, eigen_vector);
    root += rise;
    if (!(rise > 1e-15 * root)) break;  // converged (rounding may end on a step down)
  }
  eigen_value = root * scale;
  m.diagonal().array() -= root;
  eigen_vector = pcl::detail::getLargest3x3Eigenvector<Eigen::Vector3d>(m).vector;
}

// A query point's smoothed place, its normal, and the plane fit's curvature (PCL's:
// smallest eigenvalue over the trace).
struct LocalSurface {
  Eigen::Vector3d point, normal;
  double curvature = 0.0;
};

// The smoothed point and normal of one query point (pcl::MLSResult::computeMLSSurface, then
// projectQueryPoint with SIMPLE projection): the plane of the neighbours' scatter matrix, the
// query point projected on it, the Darboux frame, a weighted polynomial fit of the heights
// over it, and the point moved to the polynomial at (0, 0) with the polynomial's normal there.
// The same arithmetic as PCL's but for the order of the additions and floats where they
// suffice: the neighbours come unsorted, the sums run on a lane's worth of them at a time, the
// polynomial is fitted in units of the radius, and the normal equations are made of moments.
// False when the neighbourhood has no plane (coincident or collinear neighbours).
__attribute__((target_clones("avx2", "default"))) bool fitLocalSurface(Neighbourhood& near,
                                                                       double search_radius,
                                                                       int order,
                                                                       LocalSurface& surface) {
  Eigen::Vector3d centroid;
  Eigen::Matrix3d scatter;
  centroidAndScatter(near, centroid, scatter);
  double eigen_value;
  Eigen::Vector3d normal;
  smallestEigenvector(scatter, eigen_value, normal);
  if (!normal.allFinite()) return false;
  // The query point (the origin of the offsets) projected on the plane: the origin of the
  // Darboux frame (PCL's MLSResult::mean).
  const Eigen::Vector3d mean = normal.dot(centroid) * normal;
  const double trace = scatter.trace();
  surface.curvature = trace != 0 ? std::abs(eigen_value / trace) : trace;
  surface.point = near.query.cast<double>() + mean;
  surface.normal = normal;
  const int terms = (order + 1) * (order + 2) / 2;
  if (order <= 1 || static_cast<int>(near.count) < terms) return true;

  DarbouxFrame darboux{mean, {}, normal.unitOrthogonal(), normal};
  darboux.u_axis = normal.cross(darboux.v_axis);
  double coefficients[Polynomial<kMaxOrder>::kTerms];
  bool solved = false;
  switch (order) {
    case 2:
      solved = fitPolynomialInFrame<2, float>(near, darboux, search_radius, coefficients);
      break;
    case 3:
      solved = fitPolynomialInFrame<3, double>(near, darboux, search_radius, coefficients);
      break;
    default:
      solved = fitPolynomialInFrame<4, double>(near, darboux, search_radius, coefficients);
  }
  if (!solved || !std::isfinite(coefficients[0])) return true;  // PCL: the plane's projection
  // At (u, v) = (0, 0) the polynomial is its constant term and its gradient the coefficients of
  // v (term 1) and of u (term order + 1).
  // The polynomial is of heights in units of the radius over (u, v) in the same units: its
  // constant term scales back by the radius, its gradient is a ratio of lengths.
  surface.point += coefficients[0] * search_radius * normal;
  const Eigen::Vector3d tilted =
      normal - coefficients[order + 1] * darboux.u_axis - coefficients[1] * darboux.v_axis;
  surface.normal = tilted.normalized();
  return true;
}

// MLS smooths the points (projection on the local polynomial, PCL's SIMPLE projection) and gives
// the normal of the local surface; points with fewer than 3 neighbours are left out, as PCL's
// pcl::MovingLeastSquares does.
void smoothWithNormals(const CloudConstPtr& cluster, const NormalParams& params,
                       NormalCloud& smoothed) {
  // The search must not see NaN / inf points (an organised cluster may hold some).
  CloudConstPtr finite = cluster;
  if (!cluster->is_dense) {
    auto copy = std::make_shared<Cloud>();
    copy->header = cluster->header;
    for (const auto& p : cluster->points) {
      if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) copy->push_back(p);
    }
    if (copy->empty()) return;
    finite = copy;
  }
  const int order = std::clamp(params.polynomial_order, 0, kMaxOrder);
  // The neighbours in no order: fitLocalSurface's sums do not ask for one. (Cells of half the
  // radius cost more: 125 hash lookups per cell of only a few points.)
  GridSearch<Point> search(params.search_radius, /*sorted=*/false);
  search.setInputCloud(finite);
  // Visited cell by cell, on every free core (each point's surface depends on its neighbours
  // alone); kept in the cloud's order.
  std::vector<pcl::PointNormal> by_index(finite->size());
  std::vector<char> fitted(finite->size(), 0);
  auto smooth = [&](int i, const pcl::Indices& neighbours) {
    if (neighbours.size() < 3) return;
    Neighbourhood& neighbourhood = threadNeighbourhood();
    neighbourhood.gather(*finite, neighbours, (*finite)[i]);
    LocalSurface surface;
    if (!fitLocalSurface(neighbourhood, params.search_radius, order, surface)) return;
    pcl::PointNormal& p = by_index[i];
    p.getVector3fMap() = surface.point.cast<float>();
    p.getNormalVector3fMap() = surface.normal.cast<float>();
    p.curvature = static_cast<float>(surface.curvature);
    fitted[i] = 1;
  };
  search.forEachRadiusNeighbours(params.search_radius, smooth, freeWorkerThreads());
  smoothed.reserve(finite->size());
  for (size_t i = 0; i < by_index.size(); ++i) {
    if (fitted[i]) smoothed.push_back(by_index[i]);
  }
}

}  // namespace

void estimateNormalsMLS(const CloudConstPtr& cluster, const NormalParams& params,
                        NormalCloud& out) {
  out.clear();
  NormalCloud smoothed;
  if (cluster && !cluster->empty() && params.search_radius > 0.0f) {
    smoothWithNormals(cluster, params, smoothed);
  }

  // The cloud is in the camera frame: orient every normal towards the origin so that normals
  // of one face agree in sign (the predictor and the box fit compare normals directly).
  out.reserve(smoothed.size());
  for (const auto& p : smoothed.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) ||
        !std::isfinite(p.normal_x) || !std::isfinite(p.normal_y) || !std::isfinite(p.normal_z)) {
      continue;
    }
    pcl::PointNormal q = p;
    Eigen::Vector3f normal = q.getNormalVector3fMap();
    const float norm = normal.norm();
    if (norm < 1e-6f) continue;
    normal /= norm;
    if (normal.dot(-q.getVector3fMap()) < 0.0f) normal = -normal;
    q.getNormalVector3fMap() = normal;
    out.push_back(q);
  }
  if (cluster) out.header = cluster->header;
  out.width = static_cast<uint32_t>(out.size());
  out.height = 1;
  out.is_dense = true;
}

}  // namespace tabletop_shapes
