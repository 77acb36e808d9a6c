#include "tabletop_shapes/core/normals.h"

#include "tabletop_shapes/core/exp_lanes.h"
#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/parallel.h"

#include <pcl/common/centroid.h>
#include <pcl/common/eigen.h>
#include <pcl/surface/mls.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>

namespace tabletop_shapes {
namespace {

using Pair = double __attribute__((vector_size(16)));  // SSE2 through GCC's vector extension

}  // namespace

void centroidAndCovariance(const Cloud& cloud, const pcl::Indices& indices,
                           Eigen::Vector4d& centroid, Eigen::Matrix3d& covariance) {
  Pair sum_xy = {0.0, 0.0};
  double sum_z = 0.0;
  for (const int i : indices) {
    sum_xy += Pair{cloud[i].x, cloud[i].y};
    sum_z += cloud[i].z;
  }
  centroid = Eigen::Vector4d(sum_xy[0], sum_xy[1], sum_z, 0.0);
  centroid /= static_cast<double>(indices.size());
  centroid[3] = 1;
  const Pair mean_xy = {centroid[0], centroid[1]};
  // PCL's entries: (1,1) += y y, (1,2) += y z, (2,2) += z z, (0,0) += x x, (0,1) += y x,
  // (0,2) += z x, with x, y, z the offsets from the centroid.
  Pair xx_xy = {0.0, 0.0}, xz_yy = {0.0, 0.0}, yz_zz = {0.0, 0.0};
  for (const int i : indices) {
    const Pair xy = Pair{cloud[i].x, cloud[i].y} - mean_xy;
    const double z = cloud[i].z - centroid[2];
    xx_xy += xy * Pair{xy[0], xy[0]};
    xz_yy += Pair{z, xy[1]} * Pair{xy[0], xy[1]};
    yz_zz += Pair{xy[1], z} * Pair{z, z};
  }
  covariance << xx_xy[0], xx_xy[1], xz_yy[0],  //
      xx_xy[1], xz_yy[1], yz_zz[0],            //
      xz_yy[0], yz_zz[0], yz_zz[1];
}

namespace {

constexpr int kMaxOrder = 4;  // normals.polynomial_order's range

// The sizes of MLS's polynomial of order kOrder: its terms, as pairs; its normal equations'
// lower triangle, row a as its first a / 2 + 1 pairs (rows[a][b / 2][b % 2]: entry (a, b)).
template <int kOrder>
struct Polynomial {
  static constexpr int kTerms = (kOrder + 1) * (kOrder + 2) / 2;
  static constexpr int kPairs = (kTerms + 1) / 2;
  using Terms = Pair[kPairs];
  using Rows = Pair[kTerms][kPairs];
};

// A neighbour as the polynomial fit sees it: its offset from the projected query point over the
// Darboux frame (u, v) and along the normal; its weight (PCL's exp(-d^2 / r^2)) is kept apart,
// in an array of its own for expInPlace.
struct FrameOffset {
  double u, v, height;
};

// The polynomial's terms at (u, v) in PCL's order, u^i v^j with j fastest, as pairs (a padding
// term stays 0).
template <int kOrder>
inline void polynomialTerms(double u, double v, typename Polynomial<kOrder>::Terms& terms) {
  double scalar[2 * Polynomial<kOrder>::kPairs] = {};
  int j = 0;
  double u_power = 1;
#pragma GCC unroll 5
  for (int ui = 0; ui <= kOrder; ++ui) {
    double v_power = 1;
#pragma GCC unroll 5
    for (int vi = 0; vi <= kOrder - ui; ++vi, ++j) {
      scalar[j] = u_power * v_power;
      v_power *= v;
    }
    u_power *= u;
  }
#pragma GCC unroll 8
  for (int p = 0; p < Polynomial<kOrder>::kPairs; ++p)
    terms[p] = Pair{scalar[2 * p], scalar[2 * p + 1]};
}

// Rows [kFirstRow, kEndRow) of the normal equations' lower triangle (row a as its first
// a / 2 + 1 pairs) and, when kRightSide, the right-hand side, summed over the samples in their
// order: each entry is the sum of (weight term_a) term_b (or height) from 0, neighbour by
// neighbour. Few enough rows per pass that the sums stay in registers.
template <int kOrder, int kFirstRow, int kEndRow, bool kRightSide>
void sumRows(const std::vector<double>& weights, const std::vector<FrameOffset>& offsets,
             typename Polynomial<kOrder>::Rows& rows,
             typename Polynomial<kOrder>::Terms& right_side) {
  constexpr int kPairs = Polynomial<kOrder>::kPairs;
  Pair sums[kEndRow - kFirstRow][kPairs] = {};
  Pair right_sums[kPairs] = {};
  for (size_t k = 0; k < offsets.size(); ++k) {
    const FrameOffset& offset = offsets[k];
    Pair terms[kPairs];
    polynomialTerms<kOrder>(offset.u, offset.v, terms);
    const Pair weight_pair = {weights[k], weights[k]};
    Pair weighted[kPairs];
#pragma GCC unroll 8
    for (int p = 0; p < kPairs; ++p) weighted[p] = weight_pair * terms[p];
    if (kRightSide) {
      const Pair height_pair = {offset.height, offset.height};
#pragma GCC unroll 8
      for (int p = 0; p < kPairs; ++p) right_sums[p] += weighted[p] * height_pair;
    }
#pragma GCC unroll 15
    for (int a = kFirstRow; a < kEndRow; ++a) {
      const double w = weighted[a / 2][a % 2];
      const Pair weighted_a = {w, w};
#pragma GCC unroll 8
      for (int p = 0; p <= a / 2; ++p) sums[a - kFirstRow][p] += weighted_a * terms[p];
    }
  }
  for (int a = kFirstRow; a < kEndRow; ++a) {
    for (int p = 0; p <= a / 2; ++p) rows[a][p] = sums[a - kFirstRow][p];
  }
  if (kRightSide) {
    for (int p = 0; p < kPairs; ++p) right_side[p] = right_sums[p];
  }
}

// The rows from kFirstRow on, in passes of at most kPassPairs sums each (the first pass also
// sums the right-hand side).
template <int kOrder, int kFirstRow>
void sumRowsFrom(const std::vector<double>& weights, const std::vector<FrameOffset>& offsets,
                 typename Polynomial<kOrder>::Rows& rows,
                 typename Polynomial<kOrder>::Terms& right_side) {
  constexpr int kTerms = Polynomial<kOrder>::kTerms, kPairs = Polynomial<kOrder>::kPairs;
  constexpr int kPassPairs = 8;
  constexpr bool kRightSide = kFirstRow == 0;
  constexpr int kEndRow = [] {
    int end = kFirstRow, pairs = kRightSide ? kPairs : 0;
    while (end < kTerms && (end == kFirstRow || pairs + end / 2 + 1 <= kPassPairs))
      pairs += end / 2 + 1, ++end;
    return end;
  }();
  sumRows<kOrder, kFirstRow, kEndRow, kRightSide>(weights, offsets, rows, right_side);
  if constexpr (kEndRow < kTerms) sumRowsFrom<kOrder, kEndRow>(weights, offsets, rows, right_side);
}

// The weighted least-squares polynomial of MLS over the Darboux frame in `result` (PCL's
// weight exp(-d^2 / r^2)): its normal equations summed neighbour by neighbour, the order fixed
// at compile time so that the loops over the terms unroll. The weights and frame offsets come
// first, in a pass of their own (the weights' exp four at a time: expInPlace); the sums then
// stay in registers. They run on pairs of doubles (SSE2 through GCC's vector extension: each lane
// does the same multiply and add, so every entry is the same double as one at a time).
template <int kOrder>
void fitPolynomial(const Cloud& cloud, const pcl::Indices& neighbours, double search_radius,
                   pcl::MLSResult& result) {
  constexpr int kTerms = Polynomial<kOrder>::kTerms;
  // One buffer per thread (MLS runs on several), looked up once per call: in a shared library
  // each thread_local access is a call.
  thread_local std::vector<double> thread_weights;
  thread_local std::vector<FrameOffset> thread_offsets;
  std::vector<double>& weights = thread_weights;
  std::vector<FrameOffset>& offsets = thread_offsets;
  weights.resize(neighbours.size());
  offsets.resize(neighbours.size());
  const double squared_radius = search_radius * search_radius;
  // The frame in locals: `result` may be a thread_local, each access to it a call.
  const Eigen::Vector3d mean = result.mean, u_axis = result.u_axis, v_axis = result.v_axis,
                        normal = result.plane_normal;
  for (size_t k = 0; k < neighbours.size(); ++k) {
    const Point& p = cloud[neighbours[k]];
    const Eigen::Vector3d offset(p.x - mean[0], p.y - mean[1], p.z - mean[2]);
    weights[k] = -offset.dot(offset) / squared_radius;
    offsets[k] = {offset.dot(u_axis), offset.dot(v_axis), offset.dot(normal)};
  }
  expInPlace(weights.data(), weights.size());
  typename Polynomial<kOrder>::Rows rows;
  typename Polynomial<kOrder>::Terms right_side;
  sumRowsFrom<kOrder, 0>(weights, offsets, rows, right_side);
  Eigen::Matrix<double, kTerms, kTerms> normal_matrix;
  Eigen::Matrix<double, kTerms, 1> right;
  for (int a = 0; a < kTerms; ++a) {
    right[a] = right_side[a / 2][a % 2];
    for (int b = 0; b <= a; ++b) normal_matrix(a, b) = rows[a][b / 2][b % 2];
  }
  result.c_vec = normal_matrix.template selfadjointView<Eigen::Lower>().llt().solve(right);
}

// The local surface of point `index` as pcl::MLSResult::computeMLSSurface computes it (the
// plane of the neighbours' covariance, the query point projected on it, the Darboux frame,
// then a weighted polynomial fit of the heights over it), but with the fit's normal equations
// summed point by point in matrices of fixed size: PCL builds a coefficients x neighbours
// matrix on the heap for every point and multiplies it out with a general matrix product,
// which took most of the shape stage's instructions. The sums differ from PCL's only in the
// order of floating-point additions.
void fitLocalSurface(const Cloud& cloud, int index, const pcl::Indices& neighbours,
                     double search_radius, int order, pcl::MLSResult& result) {
  Eigen::Matrix3d covariance;
  Eigen::Vector4d centroid = Eigen::Vector4d::Zero();
  centroidAndCovariance(cloud, neighbours, centroid, covariance);
  double eigen_value;
  Eigen::Vector3d eigen_vector;
  pcl::eigen33(covariance, eigen_value, eigen_vector);
  Eigen::Vector4d plane(0, 0, 0, 0);
  plane.head<3>() = eigen_vector;
  plane[3] = -1 * plane.dot(centroid);
  result.query_point = cloud[index].getVector3fMap().cast<double>();
  if (!eigen_vector.allFinite()) {  // no plane (coincident or collinear neighbours)
    result.valid = false;
    result.mean = result.query_point;
    // No normal, so the point is dropped: PCL leaves the normal as it was, here that of the
    // point fitted before on this thread, which depends on how the points are shared out.
    result.plane_normal = eigen_vector;
    return;
  }
  result.valid = true;
  const double distance = result.query_point.dot(plane.head<3>()) + plane[3];
  result.mean = result.query_point - distance * plane.head<3>();
  result.curvature = covariance.trace();
  if (result.curvature != 0) result.curvature = std::abs(eigen_value / result.curvature);
  result.plane_normal = plane.head<3>();
  result.v_axis = result.plane_normal.unitOrthogonal();
  result.u_axis = result.plane_normal.cross(result.v_axis);
  result.num_neighbors = static_cast<int>(neighbours.size());
  result.order = order;
  const int coefficients = (order + 1) * (order + 2) / 2;
  if (order <= 1 || result.num_neighbors < coefficients) return;

  switch (order) {
    case 2:
      return fitPolynomial<2>(cloud, neighbours, search_radius, result);
    case 3:
      return fitPolynomial<3>(cloud, neighbours, search_radius, result);
    default:
      return fitPolynomial<4>(cloud, neighbours, search_radius, result);
  }
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
  const int coefficients = (order + 1) * (order + 2) / 2;
  // Sorted neighbours, as PCL's k-d tree gives them: the plane's sums run in that order. (Cells
  // of half the radius cost more: 125 hash lookups per cell of only a few points.)
  GridSearch<Point> search(params.search_radius);
  search.setInputCloud(finite);
  // Visited cell by cell, on every free core (each point's surface depends on its neighbours
  // alone); kept in the cloud's order.
  std::vector<pcl::PointNormal> by_index(finite->size());
  std::vector<char> fitted(finite->size(), 0);
  auto smooth = [&](int i, const pcl::Indices& neighbours) {
    if (neighbours.size() < 3) return;
    thread_local pcl::MLSResult surface;
    fitLocalSurface(*finite, i, neighbours, params.search_radius, order, surface);
    const pcl::MLSResult::MLSProjectionResults projected =
        surface.projectQueryPoint(pcl::MLSResult::SIMPLE, coefficients);
    pcl::PointNormal& p = by_index[i];
    p.getVector3fMap() = projected.point.cast<float>();
    p.getNormalVector3fMap() = projected.normal.cast<float>();
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
