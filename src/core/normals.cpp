#include "tabletop_shapes/core/normals.h"

#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/parallel.h"

#include <pcl/common/centroid.h>
#include <pcl/common/eigen.h>
#include <pcl/surface/mls.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>

namespace tabletop_shapes {

void centroidAndCovariance(const Cloud& cloud, const pcl::Indices& indices,
                           Eigen::Vector4d& centroid, Eigen::Matrix3d& covariance) {
  using Pair = double __attribute__((vector_size(16)));
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

// The weighted least-squares polynomial of MLS over the Darboux frame in `result` (PCL's
// weight exp(-d^2 / r^2)): its normal equations summed neighbour by neighbour, the order fixed
// at compile time so that the loops over the terms unroll. The sums run on pairs of doubles
// (SSE2 through GCC's vector extension: each lane does the same multiply and add, so every
// entry is the same double as one at a time), the lower triangle's row a as its first a / 2 + 1
// pairs: about half the instructions per neighbour of the scalar sums.
template <int kOrder>
void fitPolynomial(const Cloud& cloud, const pcl::Indices& neighbours, double search_radius,
                   pcl::MLSResult& result) {
  using Pair = double __attribute__((vector_size(16)));
  constexpr int kTerms = (kOrder + 1) * (kOrder + 2) / 2;
  constexpr int kPairs = (kTerms + 1) / 2;
  Pair rows[kTerms][kPairs] = {};  // rows[a][b / 2][b % 2]: entry (a, b), b <= a
  Pair right_side[kPairs] = {};
  Pair terms[kPairs] = {};  // a padding term stays 0
  const double squared_radius = search_radius * search_radius;
  for (const int neighbour : neighbours) {
    const Eigen::Vector3d offset(cloud[neighbour].x - result.mean[0],
                                 cloud[neighbour].y - result.mean[1],
                                 cloud[neighbour].z - result.mean[2]);
    const double weight = std::exp(-offset.dot(offset) / squared_radius);
    const double u = offset.dot(result.u_axis), v = offset.dot(result.v_axis);
    const double height = offset.dot(result.plane_normal);
    int j = 0;
    double u_power = 1;
#pragma GCC unroll 5
    for (int ui = 0; ui <= kOrder; ++ui) {  // PCL's term order: u^i v^j, j fastest
      double v_power = 1;
#pragma GCC unroll 5
      for (int vi = 0; vi <= kOrder - ui; ++vi, ++j) {
        terms[j / 2][j % 2] = u_power * v_power;
        v_power *= v;
      }
      u_power *= u;
    }
    const Pair weight_pair = {weight, weight}, height_pair = {height, height};
    Pair weighted[kPairs];
#pragma GCC unroll 8
    for (int p = 0; p < kPairs; ++p) {
      weighted[p] = weight_pair * terms[p];
      right_side[p] += weighted[p] * height_pair;
    }
#pragma GCC unroll 15
    for (int a = 0; a < kTerms; ++a) {
      const double w = weighted[a / 2][a % 2];
      const Pair weighted_a = {w, w};
#pragma GCC unroll 8
      for (int p = 0; p <= a / 2; ++p) rows[a][p] += weighted_a * terms[p];
    }
  }
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
