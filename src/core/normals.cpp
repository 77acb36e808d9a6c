#include "tabletop_shapes/core/normals.h"

#include "tabletop_shapes/core/exp_lanes.h"
#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/parallel.h"

#include <pcl/common/eigen.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

namespace tabletop_shapes {
namespace {

// Four neighbours at a time, one per lane (GCC's vector extension: one AVX instruction where
// fitLocalSurface's AVX2 clone runs, two SSE2 ones elsewhere, the same doubles either way, as
// no clone fuses a multiply and an add).
constexpr size_t kLanes = 4;
// The helpers below are always inlined: no call passes Lanes by value, so GCC's note that
// doing so without AVX changes the ABI does not apply.
#pragma GCC diagnostic ignored "-Wpsabi"
using Lanes = double __attribute__((vector_size(kLanes * sizeof(double))));

[[gnu::always_inline]] inline Lanes loadLanes(const double* values) {
  Lanes lanes;
  std::memcpy(&lanes, values, sizeof lanes);
  return lanes;
}

[[gnu::always_inline]] inline void storeLanes(double* values, Lanes lanes) {
  std::memcpy(values, &lanes, sizeof lanes);
}

[[gnu::always_inline]] inline double sumOfLanes(Lanes lanes) {
  return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
}

constexpr int kMaxOrder = 4;  // normals.polynomial_order's range

// A neighbourhood as the passes of fitLocalSurface read it, one array per quantity, padded to
// a multiple of kLanes so that each pass runs on kLanes neighbours at a time: first the
// neighbours' coordinates as the cloud holds them (floats: their offsets from the query point
// are taken in the passes, exact in doubles), then their place in the Darboux frame (u, v,
// height) with their weights. The padding neighbours sit at the query point and weigh 0, so
// they add exact zeros to every sum.
struct Neighbourhood {
  std::vector<float> px, py, pz;
  std::vector<double> u, v, height, weight;
  Eigen::Vector3d query;
  size_t count = 0, padded = 0;

  void gather(const Cloud& cloud, const pcl::Indices& indices, const Point& query_point) {
    count = indices.size();
    padded = (count + kLanes - 1) / kLanes * kLanes;
    query = query_point.getVector3fMap().cast<double>();
    if (px.size() < padded) {  // grown only: the passes read the first `padded`
      for (std::vector<float>* values : {&px, &py, &pz}) values->resize(padded);
      for (std::vector<double>* values : {&u, &v, &height, &weight}) values->resize(padded);
    }
    float *xs = px.data(), *ys = py.data(), *zs = pz.data();
    for (size_t k = 0; k < count; ++k) {
      const Point& p = cloud[indices[k]];
      xs[k] = p.x, ys[k] = p.y, zs[k] = p.z;
    }
    for (size_t k = count; k < padded; ++k)
      xs[k] = query_point.x, ys[k] = query_point.y, zs[k] = query_point.z;
  }
};

// Neighbours k .. k + kLanes - 1 of `coordinates` less the query's `origin`, in doubles.
[[gnu::always_inline]] inline Lanes offsetLanes(const float* coordinates, size_t k, double origin) {
  using FloatLanes = float __attribute__((vector_size(kLanes * sizeof(float))));
  FloatLanes floats;
  std::memcpy(&floats, coordinates + k, sizeof floats);
  return __builtin_convertvector(floats, Lanes) - origin;
}

// The neighbours' centroid (as an offset from the query point) and scatter matrix about it
// (PCL's computeCovarianceMatrix: sums, not divided by the count), from the sums of the offsets
// and of their products in one pass: offsets within the search radius, so the difference of the
// two sums loses nothing that matters (a few 1e-20 m^2 against a scatter of 1e-6 m^2 or more).
[[gnu::always_inline]] inline void centroidAndScatter(const Neighbourhood& near,
                                                      Eigen::Vector3d& centroid,
                                                      Eigen::Matrix3d& scatter) {
  Lanes sx = {}, sy = {}, sz = {}, sxx = {}, sxy = {}, sxz = {}, syy = {}, syz = {}, szz = {};
  const float *xs = near.px.data(), *ys = near.py.data(), *zs = near.pz.data();
  for (size_t k = 0, padded = near.padded; k < padded; k += kLanes) {
    const Lanes x = offsetLanes(xs, k, near.query[0]), y = offsetLanes(ys, k, near.query[1]),
                z = offsetLanes(zs, k, near.query[2]);
    sx += x, sy += y, sz += z;
    sxx += x * x, sxy += x * y, sxz += x * z;
    syy += y * y, syz += y * z, szz += z * z;
  }
  const Eigen::Vector3d first(sumOfLanes(sx), sumOfLanes(sy), sumOfLanes(sz));
  Eigen::Matrix3d second;
  second << sumOfLanes(sxx), sumOfLanes(sxy), sumOfLanes(sxz),  //
      sumOfLanes(sxy), sumOfLanes(syy), sumOfLanes(syz),        //
      sumOfLanes(sxz), sumOfLanes(syz), sumOfLanes(szz);
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

// The weighted least-squares polynomial of the heights over (u, v) (PCL's weight exp(-d^2 /
// r^2)) in `coefficients`: its normal equations from the moments, summed over kLanes
// neighbours at a time (one per lane) with the order fixed at compile time so that the loops
// unroll. False when the normal equations are not positive definite (neighbours on a line in (u,
// v)).
template <int kOrder>
[[gnu::always_inline]] inline bool fitPolynomial(const Neighbourhood& near, double* coefficients) {
  using Poly = Polynomial<kOrder>;
  constexpr int kTerms = Poly::kTerms, kDegree = Poly::kDegree;
  Lanes moments[Poly::kMoments] = {};
  Lanes right[kTerms] = {};
  for (size_t k = 0; k < near.padded; k += kLanes) {
    const Lanes u = loadLanes(&near.u[k]), v = loadLanes(&near.v[k]);
    const Lanes height = loadLanes(&near.height[k]);
    Lanes row[kDegree + 1];  // w u^i v^j for j = 0 .. kDegree - i, i rising pass by pass
    row[0] = loadLanes(&near.weight[k]);
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
  double moment_sums[Poly::kMoments];
  for (int m = 0; m < Poly::kMoments; ++m) moment_sums[m] = sumOfLanes(moments[m]);
  Eigen::Matrix<double, kTerms, kTerms> normal_matrix;
  Eigen::Matrix<double, kTerms, 1> right_side;
#pragma GCC unroll 15
  for (int a = 0; a < kTerms; ++a) {
    right_side[a] = sumOfLanes(right[a]);
#pragma GCC unroll 15
    for (int b = 0; b <= a; ++b) normal_matrix(a, b) = moment_sums[Poly::kEntryMoment[a][b]];
  }
  // Cholesky of the lower triangle in place, then the two triangular solves: a fixed size the
  // compiler unrolls (Eigen's LLT runs its blocked loops for a 6 x 6 matrix).
  double* x = right_side.data();
#pragma GCC unroll 15
  for (int j = 0; j < kTerms; ++j) {
    double diagonal = normal_matrix(j, j);
    for (int k = 0; k < j; ++k) diagonal -= normal_matrix(j, k) * normal_matrix(j, k);
    if (!(diagonal > 0.0)) return false;
    const double pivot = std::sqrt(diagonal);
    normal_matrix(j, j) = pivot;
    for (int i = j + 1; i < kTerms; ++i) {
      double entry = normal_matrix(i, j);
      for (int k = 0; k < j; ++k) entry -= normal_matrix(i, k) * normal_matrix(j, k);
      normal_matrix(i, j) = entry / pivot;
    }
  }
#pragma GCC unroll 15
  for (int i = 0; i < kTerms; ++i) {
    for (int k = 0; k < i; ++k) x[i] -= normal_matrix(i, k) * x[k];
    x[i] /= normal_matrix(i, i);
  }
#pragma GCC unroll 15
  for (int i = kTerms - 1; i >= 0; --i) {
    for (int k = i + 1; k < kTerms; ++k) x[i] -= normal_matrix(k, i) * x[k];
    x[i] /= normal_matrix(i, i);
  }
  for (int a = 0; a < kTerms; ++a) coefficients[a] = x[a];
  return true;
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
// The same arithmetic as PCL's but for the order of the additions: the neighbours come
// unsorted, the sums run on kLanes of them at a time, and the normal equations are made of moments.
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
  pcl::eigen33(scatter, eigen_value, normal);
  if (!normal.allFinite()) return false;
  // The query point (the origin of the offsets) projected on the plane: the origin of the
  // Darboux frame (PCL's MLSResult::mean).
  const Eigen::Vector3d mean = normal.dot(centroid) * normal;
  const double trace = scatter.trace();
  surface.curvature = trace != 0 ? std::abs(eigen_value / trace) : trace;
  surface.point = near.query + mean;
  surface.normal = normal;
  const int terms = (order + 1) * (order + 2) / 2;
  if (order <= 1 || static_cast<int>(near.count) < terms) return true;

  // The Darboux frame and the weights, kLanes neighbours at a time; the weights' exp four at a
  // time.
  const Eigen::Vector3d v_axis = normal.unitOrthogonal(), u_axis = normal.cross(v_axis);
  const double negative_inverse = -1.0 / (search_radius * search_radius);
  // The arrays in locals: the stores (memcpy) may alias anything, the vectors' members included.
  const float *xs = near.px.data(), *ys = near.py.data(), *zs = near.pz.data();
  double *weights = near.weight.data(), *us = near.u.data(), *vs = near.v.data(),
         *heights = near.height.data();
  for (size_t k = 0, padded = near.padded; k < padded; k += kLanes) {
    const Lanes x = offsetLanes(xs, k, near.query[0]) - mean[0];
    const Lanes y = offsetLanes(ys, k, near.query[1]) - mean[1];
    const Lanes z = offsetLanes(zs, k, near.query[2]) - mean[2];
    storeLanes(weights + k, (x * x + y * y + z * z) * negative_inverse);
    storeLanes(us + k, x * u_axis[0] + y * u_axis[1] + z * u_axis[2]);
    storeLanes(vs + k, x * v_axis[0] + y * v_axis[1] + z * v_axis[2]);
    storeLanes(heights + k, x * normal[0] + y * normal[1] + z * normal[2]);
  }
  expInPlace(near.weight.data(), near.padded);
  for (size_t k = near.count; k < near.padded; ++k) near.weight[k] = 0.0;

  double coefficients[Polynomial<kMaxOrder>::kTerms];
  bool solved = false;
  switch (order) {
    case 2:
      solved = fitPolynomial<2>(near, coefficients);
      break;
    case 3:
      solved = fitPolynomial<3>(near, coefficients);
      break;
    default:
      solved = fitPolynomial<4>(near, coefficients);
  }
  if (!solved || !std::isfinite(coefficients[0])) return true;  // PCL: the plane's projection
  // At (u, v) = (0, 0) the polynomial is its constant term and its gradient the coefficients of
  // v (term 1) and of u (term order + 1).
  surface.point += coefficients[0] * normal;
  const Eigen::Vector3d tilted =
      normal - coefficients[order + 1] * u_axis - coefficients[1] * v_axis;
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
    thread_local Neighbourhood near;  // one per thread (MLS runs on several), reused
    Neighbourhood& neighbourhood = near;
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
