// §3.3 cylinder fit (algebraic circle, eq. 10-16, refined geometrically) and the truncated cone.
//
// Everything is computed in a table frame: origin on the table plane below the object, z along
// the table normal (up), x / y in the plane. The side wall projects to a circle there; for the
// cone its radius grows linearly with the height above the table.
#include "tabletop_shapes/core/cylinder_fit.h"

#include "tabletop_shapes/core/cpu_features.h"

#include <Eigen/Dense>

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace tabletop_shapes {
namespace {

using Vec2d = Eigen::Vector2d;
using Vec3d = Eigen::Vector3d;

// A point's normal within this angle of the axis belongs to the top disc; beyond
// kSideMinAngle from the axis it belongs to the side wall (a cone of slope 0.6 still does).
const double kTopMaxAngle = 25.0 * kPi / 180.0;
const double kSideMinAngle = 45.0 * kPi / 180.0;
// Fraction of the highest points ignored when the height comes from the side wall alone.
const double kHeightQuantile = 0.995;
// Minimum number of points for a top disc to be trusted as the object's top.
const int kMinTopPoints = 10;
// Standard-error estimate of the cone slope needs a few more points than parameters.
const int kMinSidePoints = 8;
// Trimmed refit: points beyond this many robust standard deviations (1.4826 MAD) of the
// residuals are dropped; the floor keeps noise-free data from being trimmed on rounding.
const double kTrimSigmas = 3.0;
const double kTrimFloor = 0.0005;  // [m]
const int kTrimRounds = 3;
// Levenberg-Marquardt stops at a step this short (relative to 1 + |x|).
const double kConvergedStep = 1e-6;
// A circle or cone that keeps fewer of the side-wall points than this after trimming describes
// a part of the object only (seen: a box's corner, 11 of ~300 points, rmse 1.9 mm, taken for a
// cylinder r 9.6 cm). A real cylinder keeps ~97 % (noise, a handle, silhouette pixels).
const double kMinInlierFraction = 0.6;

// ---- small helpers ----

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * (values.size() - 1) + 0.5));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

double rms(const Eigen::VectorXd& residuals) {
  return residuals.size() > 0 ? std::sqrt(residuals.squaredNorm() / residuals.size()) : 0.0;
}

// Levenberg-Marquardt on sum r_i(x)^2. `model.normalEquations(x, jtj, gradient)` gives the
// sum at x, J^T J and J^T r. Returns the parameters reached; stops after max_iterations or
// when a step moves x by less than kConvergedStep: parameters are metres (and a slope). The
// circle and cone fits converge linearly, steps shrinking ~5x each (their residuals are not
// small), so a micrometre leaves ~0.25 um to go, 400 times below the 0.1 mm the figures are
// reported to, and saves the last ~4 of ~10 iterations (each a pass over all the points).
// Shared by the circle and the cone fit.
template <typename Model>
Eigen::VectorXd levenbergMarquardt(const Model& model, Eigen::VectorXd x, int max_iterations) {
  // The small systems' storage, kept across iterations and trials.
  Eigen::MatrixXd jtj(x.size(), x.size()), trial_jtj(x.size(), x.size()),
      damped(x.size(), x.size());
  Eigen::VectorXd gradient(x.size()), trial_gradient(x.size()), step(x.size()), trial(x.size());
  Eigen::LDLT<Eigen::MatrixXd> solver(x.size());
  double cost = model.normalEquations(x, jtj, gradient);
  double lambda = 1e-3;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    bool improved = false;
    while (lambda < 1e12) {
      damped = jtj;
      damped.diagonal() += lambda * (jtj.diagonal().array() + 1e-12).matrix();
      step = solver.compute(damped).solve(-gradient);
      if (!step.allFinite()) break;
      trial = x + step;
      // With its normal equations: most trials are taken (~4 in 5), and they cost little more
      // than the sum alone.
      const double trial_cost = model.normalEquations(trial, trial_jtj, trial_gradient);
      if (std::isfinite(trial_cost) && trial_cost <= cost) {
        const bool converged = step.norm() <= kConvergedStep * (1.0 + x.norm());
        x.swap(trial);
        cost = trial_cost;
        jtj.swap(trial_jtj);
        gradient.swap(trial_gradient);
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = !converged;
        break;
      }
      lambda *= 10.0;
    }
    if (!improved) break;
  }
  return x;
}

// The model with per-residual weights (0 or 1 for trimming) applied to each residual and its
// Jacobian row, so that the trimmed fit reuses the plain least-squares solver.
template <typename Residuals>
Residuals weighted(Residuals model, const Eigen::VectorXd& weights) {
  model.weights = &weights;
  return model;
}

struct TrimmedSolution {
  Eigen::VectorXd x;
  Eigen::VectorXd residuals;  // unweighted, all points
  Eigen::VectorXd inliers;    // 1 = used, 0 = trimmed
  int inlier_count = 0;
  double rmse = 0.0;  // over the inliers
};

// Least squares that ignores gross outliers (a mug's handle, flying pixels at the silhouette):
// fit, drop points beyond kTrimSigmas robust standard deviations of the residuals, refit from
// there; stops when the inlier set no longer changes. Gaussian noise loses ~0.3 % of its points,
// symmetrically, so no bias is added on clean data.
template <typename Residuals>
TrimmedSolution trimmedLeastSquares(const Residuals& model, const Eigen::VectorXd& start, int n,
                                    int max_iterations) {
  TrimmedSolution solution;
  solution.x = start;
  solution.inliers = Eigen::VectorXd::Ones(n);
  solution.residuals.resize(n);
  for (int round = 0; round <= kTrimRounds; ++round) {
    solution.x = levenbergMarquardt(weighted(model, solution.inliers), solution.x, max_iterations);
    model(solution.x, solution.residuals);
    if (round == kTrimRounds) break;
    std::vector<double> magnitudes(n);
    for (int i = 0; i < n; ++i) magnitudes[i] = std::abs(solution.residuals[i]);
    const double threshold = std::max(kTrimSigmas * 1.4826 * quantile(magnitudes, 0.5), kTrimFloor);
    const Eigen::VectorXd inliers =
        (solution.residuals.array().abs() <= threshold).template cast<double>();
    if (inliers.sum() < kMinSidePoints || inliers == solution.inliers) break;
    solution.inliers = inliers;
  }
  solution.inlier_count = static_cast<int>(solution.inliers.sum());
  solution.rmse =
      solution.inlier_count > 0
          ? std::sqrt((solution.residuals.array() * solution.inliers.array()).square().sum() /
                      solution.inlier_count)
          : 0.0;
  return solution;
}

using DoublePair = double __attribute__((vector_size(16)));
struct RootOfPair {
  static DoublePair of(DoublePair value) {
#ifdef __SSE2__
    return (DoublePair)_mm_sqrt_pd((__m128d)value);  // correctly rounded, as std::sqrt
#else
    return DoublePair{std::sqrt(value[0]), std::sqrt(value[1])};
#endif
  }
};
#if defined(__x86_64__) && defined(__GNUC__)
#define TABLETOP_SHAPES_FOUR_DOUBLES 1
// Lanes of four doubles are passed only within AVX2 functions and always-inlined ones: GCC's
// note that passing them without AVX changes the ABI does not apply.
#pragma GCC diagnostic ignored "-Wpsabi"
using DoubleQuad = double __attribute__((vector_size(32)));
struct RootOfQuad {
  __attribute__((target("avx2"))) static DoubleQuad of(DoubleQuad value) {
    return (DoubleQuad)_mm256_sqrt_pd((__m256d)value);
  }
};
bool hasFourDoubleLanes() { return cpuHasAvx2(); }
#endif

// Geometric residuals |p - c| - r(h) of points on a round wall: without heights a circle,
// parameters (cx, cy, r); with them a cone, (cx, cy, r0, s), r(h) = r0 + s h. With `weights`,
// each residual and its Jacobian row times its weight.
struct RoundWallResiduals {
  const std::vector<Vec2d>& points;
  const std::vector<double>* heights = nullptr;
  const Eigen::VectorXd* weights = nullptr;

  // The residuals at x.
  void operator()(const Eigen::VectorXd& x, Eigen::VectorXd& residuals) const {
    const Vec2d centre(x[0], x[1]);
    for (size_t i = 0; i < points.size(); ++i) {
      const double distance = (points[i] - centre).norm();
      const double height = heights ? (*heights)[i] : 0.0;
      const double weight = weights ? (*weights)[i] : 1.0;
      residuals[i] = (distance - (heights ? x[2] + x[3] * height : x[2])) * weight;
    }
  }

  // Levenberg-Marquardt's normal equations at x, in one pass over the points without storing
  // the residuals or the Jacobian (Levenberg-Marquardt spent most of its instructions writing
  // and then reading them): J^T J in `jtj`, J^T r in `gradient`; returns r^T r. Four points at a
  // time where the CPU has AVX2, else two.
  double normalEquations(const Eigen::VectorXd& x, Eigen::MatrixXd& jtj,
                         Eigen::VectorXd& gradient) const {
#ifdef TABLETOP_SHAPES_FOUR_DOUBLES
    if (hasFourDoubleLanes()) return normalEquationsInFourLanes(x, jtj, gradient);
#endif
    return withOptions<DoublePair, RootOfPair>(x, jtj, gradient);
  }

 private:
#ifdef TABLETOP_SHAPES_FOUR_DOUBLES
  __attribute__((target("avx2"))) double normalEquationsInFourLanes(
      const Eigen::VectorXd& x, Eigen::MatrixXd& jtj, Eigen::VectorXd& gradient) const {
    return withOptions<DoubleQuad, RootOfQuad>(x, jtj, gradient);
  }
#endif

  // The model's options chosen once, outside the loop over the points.
  template <typename Doubles, typename Root>
  [[gnu::always_inline]] double withOptions(const Eigen::VectorXd& x, Eigen::MatrixXd& jtj,
                                            Eigen::VectorXd& gradient) const {
    if (heights) {
      return weights ? sumsInLanes<Doubles, Root, true, true>(x, jtj, gradient)
                     : sumsInLanes<Doubles, Root, true, false>(x, jtj, gradient);
    }
    return weights ? sumsInLanes<Doubles, Root, false, true>(x, jtj, gradient)
                   : sumsInLanes<Doubles, Root, false, false>(x, jtj, gradient);
  }

  // normalEquations on lanes of Doubles, one point per lane; the sums' lanes added at the end.
  // At the centre the direction is undefined; any unit vector keeps J finite.
  template <typename Doubles, typename Root, bool kHeights, bool kWeights>
  [[gnu::always_inline]] double sumsInLanes(const Eigen::VectorXd& x, Eigen::MatrixXd& jtj,
                                            Eigen::VectorXd& gradient) const {
    constexpr int kLanes = sizeof(Doubles) / sizeof(double);
    constexpr int kParameters = kHeights ? 4 : 3;
    constexpr int kProducts = kParameters * (kParameters + 1) / 2;
    const Doubles cx = Doubles{} + x[0], cy = Doubles{} + x[1], r0 = Doubles{} + x[2];
    const Doubles slope = Doubles{} + (kHeights ? x[3] : 0.0);
    const Doubles zero = {}, one = zero + 1.0, tiny = zero + 1e-12;
    Doubles products[kProducts] = {}, along[kParameters] = {}, squares = {};
    // One lane per point; a lane of weight 0 (beyond the last point) adds nothing.
    auto add = [&](Doubles px, Doubles py, Doubles height, Doubles weight)
        __attribute__((always_inline)) {
      const Doubles dx = px - cx, dy = py - cy;
      const Doubles distance = Root::of(dx * dx + dy * dy);
      const Doubles residual = (distance - (kHeights ? r0 + slope * height : r0)) * weight;
      const auto away = distance > tiny;  // false for NaN, as `distance > 1e-12`
      const Doubles row[4] = {-(away ? dx / distance : one) * weight,
                              -(away ? dy / distance : zero) * weight, -weight, -height * weight};
      int product = 0;
#pragma GCC unroll 4
      for (int a = 0; a < kParameters; ++a) {
#pragma GCC unroll 4
        for (int b = a; b < kParameters; ++b) products[product++] += row[a] * row[b];
        along[a] += row[a] * residual;
      }
      squares += residual * residual;
    };
    const size_t n = points.size(), whole = n - n % kLanes;
    const double* coordinates = points.empty() ? nullptr : points.front().data();
    for (size_t i = 0; i < whole; i += kLanes) {
      Doubles first, second;  // x y of the lanes' points, interleaved
      std::memcpy(&first, coordinates + 2 * i, sizeof first);
      std::memcpy(&second, coordinates + 2 * i + kLanes, sizeof second);
      Doubles px, py, height = zero, weight = one;
      if constexpr (kLanes == 2) {
        px = __builtin_shufflevector(first, second, 0, 2);
        py = __builtin_shufflevector(first, second, 1, 3);
      } else {
        px = __builtin_shufflevector(first, second, 0, 2, 4, 6);
        py = __builtin_shufflevector(first, second, 1, 3, 5, 7);
      }
      if (kHeights) std::memcpy(&height, heights->data() + i, sizeof height);
      if (kWeights) std::memcpy(&weight, weights->data() + i, sizeof weight);
      add(px, py, height, weight);
    }
    if (whole < n) {
      Doubles px = cx + 1.0, py = cy, height = zero, weight = zero;
      for (size_t i = whole; i < n; ++i) {
        px[i - whole] = points[i].x(), py[i - whole] = points[i].y();
        if (kHeights) height[i - whole] = (*heights)[i];
        weight[i - whole] = kWeights ? (*weights)[i] : 1.0;
      }
      add(px, py, height, weight);
    }
    auto sumOf = [](Doubles lanes) {
      double sum = lanes[0];
      for (int lane = 1; lane < kLanes; ++lane) sum += lanes[lane];
      return sum;
    };
    int product = 0;
    for (int a = 0; a < kParameters; ++a) {
      for (int b = a; b < kParameters; ++b) jtj(a, b) = jtj(b, a) = sumOf(products[product++]);
      gradient[a] = sumOf(along[a]);
    }
    return sumOf(squares);
  }
};

std::vector<Vec2d> toDouble(const std::vector<Eigen::Vector2f>& points) {
  std::vector<Vec2d> out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back(p.cast<double>());
  return out;
}

// Algebraic circle (eq. 10-16) on double points. The points are centred and scaled first so
// that the normal equations stay well conditioned for any offset of the frame.
Circle algebraicCircle(const std::vector<Vec2d>& points) {
  Circle circle;
  if (points.size() < 3) return circle;
  Vec2d mean = Vec2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  // Eigenvalues of the symmetric 2x2 scatter in closed form.
  const double half_trace = 0.5 * scatter.trace();
  const double spread = std::hypot(0.5 * (scatter(0, 0) - scatter(1, 1)), scatter(0, 1));
  const double largest = half_trace + spread;
  // Collinear (or coincident) points: no circle, only a line (or nothing).
  if (!(largest > 0.0) || half_trace - spread <= 1e-12 * largest) return circle;
  const double scale = std::sqrt(largest / static_cast<double>(points.size()));

  // x^2 + y^2 - 2Ax - 2By - C = 0  <=>  [2x 2y 1] [A B C]^T = x^2 + y^2 (eq. 10-16), solved
  // by its normal equations: sums over the points, centred and scaled (their scatter's larger
  // eigenvalue 1 per point, the smaller one above 1e-12 of it) so that the 3 x 3 system stays
  // well conditioned. A pivoting QR of the n x 3 design matrix cost ~4 times more, and this
  // circle only starts the geometric fit or ranks the lying cylinder's start axes.
  double sum_x = 0.0, sum_y = 0.0, sum_xx = 0.0, sum_xy = 0.0, sum_yy = 0.0;
  double sum_z = 0.0, sum_xz = 0.0, sum_yz = 0.0;  // z = x^2 + y^2
  for (const Vec2d& p : points) {
    const Vec2d q = (p - mean) / scale;
    const double z = q.squaredNorm();
    sum_x += q.x();
    sum_y += q.y();
    sum_xx += q.x() * q.x();
    sum_xy += q.x() * q.y();
    sum_yy += q.y() * q.y();
    sum_z += z;
    sum_xz += q.x() * z;
    sum_yz += q.y() * z;
  }
  Eigen::Matrix3d normal_matrix;
  normal_matrix << 4.0 * sum_xx, 4.0 * sum_xy, 2.0 * sum_x, 4.0 * sum_xy, 4.0 * sum_yy, 2.0 * sum_y,
      2.0 * sum_x, 2.0 * sum_y, static_cast<double>(points.size());
  const Eigen::Vector3d abc =
      normal_matrix.ldlt().solve(Eigen::Vector3d(2.0 * sum_xz, 2.0 * sum_yz, sum_z));
  const double radius_squared = abc[0] * abc[0] + abc[1] * abc[1] + abc[2];
  if (!abc.allFinite() || !(radius_squared > 0.0)) return circle;
  const Vec2d centre = mean + scale * Vec2d(abc[0], abc[1]);
  const double radius = scale * std::sqrt(radius_squared);

  Eigen::VectorXd residuals(points.size());
  RoundWallResiduals{points}(Eigen::Vector3d(centre.x(), centre.y(), radius), residuals);
  circle.center = centre.cast<float>();
  circle.radius = static_cast<float>(radius);
  circle.rmse = static_cast<float>(rms(residuals));
  circle.ok = std::isfinite(circle.radius) && std::isfinite(circle.rmse);
  return circle;
}

Circle geometricCircle(const std::vector<Vec2d>& points, const Circle& initial,
                       int max_iterations) {
  const Circle start = initial.ok ? initial : algebraicCircle(points);
  if (!start.ok || points.size() < 3) return Circle{};
  const Eigen::VectorXd x = levenbergMarquardt(
      RoundWallResiduals{points}, Eigen::Vector3d(start.center.x(), start.center.y(), start.radius),
      std::max(0, max_iterations));
  Eigen::VectorXd residuals(points.size());
  RoundWallResiduals{points}(x, residuals);
  Circle circle;
  circle.center = Vec2d(x[0], x[1]).cast<float>();
  circle.radius = static_cast<float>(std::abs(x[2]));
  circle.rmse = static_cast<float>(rms(residuals));
  circle.ok = x.allFinite() && circle.radius > 0.0f;
  return circle;
}

// ---- the object in the table frame ----

struct TableFrame {
  Eigen::Matrix3d rotation;  // rows: table x, table y, table normal (cloud -> table)
  Vec3d origin;              // on the table plane, below the object's centroid
  Vec3d toTable(const Vec3d& p) const { return rotation * (p - origin); }
  Vec3d toCloud(const Vec3d& q) const { return rotation.transpose() * q + origin; }
};

// The object's points split by what they are: side wall (radius), all (height).
struct RoundObjectPoints {
  bool ok = false;
  std::string reason;
  TableFrame frame;
  std::vector<Vec2d> side_xy;       // side wall, projected on the table
  std::vector<double> side_height;  // their height above the table
  // Their normals' part along the table (camera-facing normals, normals.h); zero when unknown.
  std::vector<Vec2d> side_normal;
  double height = 0.0;
  bool top_seen = false;  // height from the top disc (else from the side wall)
};

// Height of the top from the heights of the points on it: their median, unless a distinct
// group stands above it (beyond kTrimSigmas robust deviations, at least a twentieth of them),
// such as a can's rim above its recessed lid; then that group's median, so that the solid
// reaches the points' own top (can heights came out 4-7 mm short on real frames).
double topHeight(const std::vector<double>& top_heights) {
  const double median = quantile(top_heights, 0.5);
  std::vector<double> deviations;
  deviations.reserve(top_heights.size());
  for (double h : top_heights) deviations.push_back(std::abs(h - median));
  const double sigma = std::max(1.4826 * quantile(deviations, 0.5), kTrimFloor);
  std::vector<double> above;
  for (double h : top_heights) {
    if (h > median + kTrimSigmas * sigma) above.push_back(h);
  }
  const size_t needed = std::max<size_t>(kMinTopPoints / 2, top_heights.size() / 20);
  return above.size() >= needed ? quantile(above, 0.5) : median;
}

RoundObjectPoints splitObject(const NormalCloud& object, const Plane& table,
                              const CylinderParams& params) {
  RoundObjectPoints out;
  const double normal_length = table.normal.cast<double>().norm();
  if (!std::isfinite(normal_length) || !std::isfinite(table.d) || normal_length < 1e-6) {
    out.reason = "invalid table plane";
    return out;
  }
  const Vec3d up = table.normal.cast<double>() / normal_length;
  const double table_d = table.d / normal_length;
  std::vector<Vec3d> positions;
  std::vector<Vec3d> normals;
  positions.reserve(object.size());
  normals.reserve(object.size());
  Vec3d centroid = Vec3d::Zero();
  for (const auto& p : object.points) {
    const Vec3d position(p.x, p.y, p.z);
    if (!position.allFinite()) continue;
    positions.push_back(position);
    normals.push_back(Vec3d(p.normal_x, p.normal_y, p.normal_z));
    centroid += position;
  }
  if (positions.size() < 3) {
    out.reason = "too few points (" + std::to_string(positions.size()) + ")";
    return out;
  }
  centroid /= static_cast<double>(positions.size());

  TableFrame& frame = out.frame;
  const Vec3d x_axis = up.unitOrthogonal();
  frame.rotation.row(0) = x_axis.transpose();
  frame.rotation.row(1) = up.cross(x_axis).transpose();
  frame.rotation.row(2) = up.transpose();
  frame.origin = centroid - (up.dot(centroid) + table_d) * up;

  std::vector<Vec3d> local(positions.size());
  std::vector<double> heights(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    local[i] = frame.toTable(positions[i]);
    heights[i] = local[i].z();
  }
  // Height (the paper: the largest distance to the table, outliers being removed upstream).
  // A surviving flying pixel or noise spike would add to the max directly, so: the median
  // height of the top disc when it is seen (unbiased under symmetric noise), else a high
  // quantile of all heights (costs < 0.5 % of the height range on a uniformly sampled wall).
  const double high = quantile(heights, kHeightQuantile);
  const double top_band = std::max(static_cast<double>(params.top_margin), 0.0);
  std::vector<double> top_heights;
  for (size_t i = 0; i < positions.size(); ++i) {
    const double n_norm = normals[i].norm();
    if (!(n_norm > 0.0) || !normals[i].allFinite()) continue;
    const double cos_axis = std::abs(normals[i].dot(up)) / n_norm;
    if (cos_axis >= std::cos(kTopMaxAngle) && heights[i] >= high - top_band) {
      top_heights.push_back(heights[i]);
    }
  }
  out.top_seen = static_cast<int>(top_heights.size()) >= kMinTopPoints;
  out.height = out.top_seen ? topHeight(top_heights) : high;
  if (!(out.height > 0.0)) {
    out.reason = "object has no height above the table";
    return out;
  }

  // Side wall: normal far from the axis (unknown normals count as side), and below the rim,
  // where smoothing blends the top disc into the wall (kept when it would leave too few).
  const double rim = out.height - top_band;
  for (int pass = 0; pass < 2 && out.side_xy.size() < kMinSidePoints; ++pass) {
    out.side_xy.clear();
    out.side_height.clear();
    out.side_normal.clear();
    for (size_t i = 0; i < positions.size(); ++i) {
      const double n_norm = normals[i].norm();
      const bool normal_known = n_norm > 0.0 && normals[i].allFinite();
      if (normal_known && std::abs(normals[i].dot(up)) / n_norm > std::cos(kSideMinAngle)) {
        continue;
      }
      if (pass == 0 && heights[i] > rim) continue;
      out.side_xy.push_back(local[i].head<2>());
      out.side_height.push_back(heights[i]);
      out.side_normal.push_back(normal_known ? Vec2d((frame.rotation * normals[i]).head<2>())
                                             : Vec2d::Zero());
    }
  }
  if (out.side_xy.size() < kMinSidePoints) {
    out.reason = "too few side-wall points (" + std::to_string(out.side_xy.size()) + ")";
    return out;
  }
  out.ok = true;
  return out;
}

// `split` with only the side-wall points for which `keep(i)` holds.
template <typename Keep>
RoundObjectPoints sideWallWhere(const RoundObjectPoints& split, const Keep& keep) {
  RoundObjectPoints kept = split;
  kept.side_xy.clear();
  kept.side_height.clear();
  kept.side_normal.clear();
  for (size_t i = 0; i < split.side_xy.size(); ++i) {
    if (!keep(i)) continue;
    kept.side_xy.push_back(split.side_xy[i]);
    kept.side_height.push_back(split.side_height[i]);
    kept.side_normal.push_back(split.side_normal[i]);
  }
  return kept;
}

Eigen::Quaternionf axisUp(const TableFrame& frame) {
  // Columns of rotation^T are the table axes in the cloud frame; z is the table normal.
  return Eigen::Quaternionf(frame.rotation.transpose().cast<float>()).normalized();
}

std::string formatRadius(const char* what, double radius, const CylinderParams& params) {
  std::ostringstream reason;
  reason << what << " " << radius << " m outside [" << params.min_radius << ", "
         << params.max_radius << "] m";
  return reason.str();
}

bool radiusInBounds(double radius, const CylinderParams& params) {
  return std::isfinite(radius) && radius >= params.min_radius && radius <= params.max_radius;
}

struct ConeSolution {
  Eigen::Vector4d x = Eigen::Vector4d::Zero();  // cx, cy, r0, slope
  double rmse = 0.0;
  int points = 0;
  double slope_stderr = std::numeric_limits<double>::infinity();
};

ConeSolution solveCone(const RoundObjectPoints& split, const Circle& cylinder, int max_iterations) {
  const RoundWallResiduals residual_model{split.side_xy, &split.side_height};
  const int n = static_cast<int>(split.side_xy.size());
  const TrimmedSolution trimmed = trimmedLeastSquares(
      residual_model,
      Eigen::Vector4d(cylinder.center.x(), cylinder.center.y(), cylinder.radius, 0.0), n,
      std::max(0, max_iterations));
  ConeSolution solution;
  solution.x = trimmed.x;
  solution.rmse = trimmed.rmse;
  solution.points = trimmed.inlier_count;
  Eigen::MatrixXd jtj(4, 4);
  Eigen::VectorXd gradient(4);
  const double squares =
      weighted(residual_model, trimmed.inliers).normalEquations(trimmed.x, jtj, gradient);
  // Covariance of the estimate on the inliers: sigma^2 (J^T J)^-1, sigma^2 = SSR / (m - 4).
  // Residuals of neighbouring points are correlated (voxel grid, MLS smoothing), so this is
  // optimistic; the decision adds ConeParams::min_slope on top.
  const Eigen::FullPivLU<Eigen::Matrix4d> lu{Eigen::Matrix4d(jtj)};
  const int m = trimmed.inlier_count;
  if (m > 4 && lu.isInvertible()) {
    const double variance = squares / (m - 4);
    const double slope_variance = variance * lu.inverse()(3, 3);
    if (slope_variance >= 0.0) solution.slope_stderr = std::sqrt(slope_variance);
  }
  return solution;
}

// False (with the reason in `fit`) when the trimmed fit kept too few of `total` points.
bool keepsEnoughPoints(int inliers, size_t total, ShapeFit& fit) {
  if (inliers >= kMinInlierFraction * static_cast<double>(total)) return true;
  fit.reason = "only " + std::to_string(inliers) + " of " + std::to_string(total) +
               " side-wall points fit the " + shapeTypeName(fit.type);
  return false;
}

// The side-wall points on an inner wall, 1 (else 0), by the side of the axis (of the `initial`
// circle) their normals face: the camera-facing normal of an outer wall points away from the
// axis, that of the inner wall of an open container seen over its rim (a mug's) towards it.
std::vector<double> innerWallPoints(const RoundObjectPoints& split, const Circle& initial,
                                    int& count) {
  const Vec2d centre = initial.center.cast<double>();
  std::vector<double> inner(split.side_xy.size(), 0.0);
  count = 0;
  for (size_t i = 0; i < inner.size(); ++i) {
    inner[i] = split.side_normal[i].dot(split.side_xy[i] - centre) < 0.0 ? 1.0 : 0.0;
    count += inner[i] > 0.0;
  }
  return inner;
}

// The circle of the outer side wall, trimmed, from `initial`: (cx, cy, r). An inner wall seen
// over the rim (innerWallPoints) is a circle of its own, a wall's thickness smaller on the same
// axis: both are fitted together, r for the outer wall and r + x[3] for the inner one, so the
// inner wall still holds the centre and no longer pulls the radius in (rendered mugs, wall 4 mm,
// came out 2 mm = 5 % small on every view; a circle through the outer wall alone, a third of
// the mug's circumference, was pulled 4-37 mm wide by the handle).
constexpr double kMaxWallFraction = 0.25;

TrimmedSolution wallCircle(const RoundObjectPoints& split, const Circle& initial,
                           int max_iterations) {
  const int n = static_cast<int>(split.side_xy.size());
  int inner_count = 0;
  const std::vector<double> inner = innerWallPoints(split, initial, inner_count);
  const TrimmedSolution plain = trimmedLeastSquares(
      RoundWallResiduals{split.side_xy},
      Eigen::Vector3d(initial.center.x(), initial.center.y(), initial.radius), n, max_iterations);
  if (inner_count < kMinSidePoints || n - inner_count < kMinSidePoints) return plain;
  TrimmedSolution two_walls = trimmedLeastSquares(
      RoundWallResiduals{split.side_xy, &inner},
      Eigen::Vector4d(plain.x[0], plain.x[1], plain.x[2], 0.0), n, max_iterations);
  // Two concentric walls: the inner one inside, a container's wall apart (at most a quarter of
  // the radius: mugs' walls are 3-8 mm), and the one circle through both between them (a handle
  // took the outer circle of a rendered mug 9 mm wide, 24 % over, without these bounds).
  const double thickness = -two_walls.x[3], widening = two_walls.x[2] - plain.x[2];
  if (!two_walls.x.allFinite() || !(thickness > 0.0) ||
      thickness > kMaxWallFraction * two_walls.x[2] || widening < 0.0 || widening > thickness) {
    return plain;
  }
  two_walls.x.conservativeResize(3);
  return two_walls;
}

// Cylinder from an already split object; `circle` receives the refined circle.
ShapeFit cylinderFromSplit(const RoundObjectPoints& split, const CylinderParams& params,
                           Circle& circle) {
  ShapeFit fit;
  fit.type = ShapeType::Cylinder;
  const Circle initial = algebraicCircle(split.side_xy);
  if (!initial.ok) {
    fit.reason = "side-wall points are collinear in the table plane (no circle)";
    return fit;
  }
  const TrimmedSolution trimmed =
      wallCircle(split, initial, std::max(0, params.max_refine_iterations));
  circle.center = trimmed.x.head<2>().cast<float>();
  circle.radius = static_cast<float>(std::abs(trimmed.x[2]));
  circle.rmse = static_cast<float>(trimmed.rmse);
  circle.ok = trimmed.x.allFinite() && circle.radius > 0.0f;
  if (!circle.ok) {
    fit.reason = "geometric circle refinement failed";
    return fit;
  }
  fit.radius = circle.radius;
  fit.height = static_cast<float>(split.height);
  fit.points = trimmed.inlier_count;
  fit.rmse = circle.rmse;
  fit.orientation = axisUp(split.frame);
  fit.center = split.frame.toCloud(Vec3d(circle.center.x(), circle.center.y(), split.height / 2))
                   .cast<float>();
  if (!radiusInBounds(circle.radius, params)) {
    fit.reason = formatRadius("radius", circle.radius, params);
    return fit;
  }
  fit.ok = keepsEnoughPoints(trimmed.inlier_count, split.side_xy.size(), fit);
  return fit;
}

ShapeFit coneFromSplit(const RoundObjectPoints& split, const Circle& cylinder_circle,
                       const CylinderParams& params, ConeSolution& solution) {
  ShapeFit fit;
  fit.type = ShapeType::Cone;
  solution = solveCone(split, cylinder_circle, params.max_refine_iterations);
  const Eigen::Vector4d& x = solution.x;
  fit.radius_bottom = static_cast<float>(x[2]);
  fit.radius_top = static_cast<float>(x[2] + x[3] * split.height);
  fit.radius = 0.5f * (fit.radius_bottom + fit.radius_top);
  fit.height = static_cast<float>(split.height);
  fit.points = solution.points;
  fit.rmse = static_cast<float>(solution.rmse);
  fit.orientation = axisUp(split.frame);
  fit.center = split.frame.toCloud(Vec3d(x[0], x[1], split.height / 2)).cast<float>();
  if (!x.allFinite()) {
    fit.reason = "cone refinement diverged";
  } else if (!radiusInBounds(fit.radius_bottom, params)) {
    fit.reason = formatRadius("bottom radius", fit.radius_bottom, params);
  } else if (!radiusInBounds(fit.radius_top, params)) {
    fit.reason = formatRadius("top radius", fit.radius_top, params);
  } else {
    fit.ok = keepsEnoughPoints(solution.points, split.side_xy.size(), fit);
  }
  return fit;
}

// Distance of q to the segment a-b (2-D or 3-D).
template <typename Vector>
double segmentDistance(const Vector& q, const Vector& a, const Vector& b) {
  const Vector ab = b - a;
  const double length_squared = ab.squaredNorm();
  const double t =
      length_squared > 0.0 ? std::clamp((q - a).dot(ab) / length_squared, 0.0, 1.0) : 0.0;
  return (q - (a + t * ab)).norm();
}

// A fitted cylinder or truncated cone in its own frame: z along the axis from the bottom disc
// (z = 0) to the top (z = height); rims as (radius, height).
struct RoundSolid {
  explicit RoundSolid(const ShapeFit& round)
      : fit(round),
        height(round.height),
        bottom_rim(round.type == ShapeType::Cone ? round.radius_bottom : round.radius, 0.0),
        top_rim(round.type == ShapeType::Cone ? round.radius_top : round.radius, round.height),
        top_centre(0.0, round.height) {}
  Vec3d local(const Eigen::Vector3f& point) const {
    return (fit.orientation.conjugate() * (point - fit.center)).cast<double>() +
           Vec3d(0.0, 0.0, 0.5 * height);
  }
  const ShapeFit& fit;
  double height;
  Vec2d bottom_rim, top_rim, top_centre;
};

// Whether the wall facing the camera contradicts the cone's taper: there, how far the points
// stand out towards the camera grows with their height as the radius does (dr/dh = the slope,
// times cos of the azimuth, > 0.87 in the strip taken). A fitted slope can also come from the
// centre and the slope trading off between the near wall seen low and a far wall (a bowl's
// inside) seen high, which turned a bowl's taper upside down; the near wall alone is free of
// that. It contradicts when a strip of at least kMinSidePoints over a third of the height
// tapers the other way.
bool nearWallContradictsTaper(const RoundObjectPoints& split, const ConeSolution& cone) {
  const Vec2d centre(cone.x[0], cone.x[1]);
  const Vec2d camera = split.frame.toTable(Vec3d::Zero()).head<2>() - centre;
  if (camera.norm() < 1e-6) return false;
  const Vec2d towards = camera.normalized(), across(-towards.y(), towards.x());
  std::vector<double> heights, outward;
  for (size_t i = 0; i < split.side_xy.size(); ++i) {
    const Vec2d offset = split.side_xy[i] - centre;
    const double radius = cone.x[2] + cone.x[3] * split.side_height[i];
    if (offset.dot(towards) <= 0.0 || std::abs(offset.dot(across)) > 0.5 * radius) continue;
    heights.push_back(split.side_height[i]);
    outward.push_back(offset.dot(towards));
  }
  if (heights.size() < kMinSidePoints) return false;
  const auto [low, high] = std::minmax_element(heights.begin(), heights.end());
  if (*high - *low < split.height / 3.0) return false;
  const double n = static_cast<double>(heights.size());
  double mean_h = 0.0, mean_o = 0.0;
  for (size_t i = 0; i < heights.size(); ++i) {
    mean_h += heights[i] / n;
    mean_o += outward[i] / n;
  }
  double covariance = 0.0, variance = 0.0;
  for (size_t i = 0; i < heights.size(); ++i) {
    covariance += (heights[i] - mean_h) * (outward[i] - mean_o);
    variance += (heights[i] - mean_h) * (heights[i] - mean_h);
  }
  const double seen_slope = covariance / variance;
  const double fitted_slope = cone.x[3];
  return seen_slope * fitted_slope < 0.0;
}

// A cone's radius changes over its height by at least kMinTaper and kMinTaperToNoise times the
// RMS residual of its wall. Below that the cylinder of the mean radius stays within 2 mm of the
// cone everywhere, and the slope is no longer the object's: on short wide cans (33 mm tall, a
// side wall of 15 mm seen between the table band and the rim band) the smoothed wall leaned
// outwards by 1-6 mm with a slope of 3-10 standard errors, while the paper's beaker tapers by
// 7.5 mm and the bowls by 35 mm.
constexpr double kMinTaper = 0.004;  // [m]
constexpr double kMinTaperToNoise = 4.0;

bool taperIsMeasurable(const ConeSolution& cone, double height) {
  const double taper = std::abs(cone.x[3]) * height;
  return taper >= std::max(kMinTaper, kMinTaperToNoise * cone.rmse);
}

// A taper narrowing upwards is a cone only when it is straight: the side wall's distance from
// the cone's axis follows the cone's radius in every height slice, to within
// kProfileTolerance of the radius (at least kProfileFloor). A bottle's body, shoulder and neck
// narrow upwards too, but in steps: a cone through them was 8-11 mm off its points in the
// lowest and highest slices, and came out 25-45 % wider than the body at the bottom.
constexpr int kProfileSlices = 4;
constexpr double kProfileTolerance = 0.1;
constexpr double kProfileFloor = 0.0025;  // [m]

// The median, per height slice of the side wall (kProfileSlices), of `offset(i)` over the
// slice's side-wall points; slices with fewer than kMinSidePoints are left out.
template <typename Offset>
std::vector<double> sliceMedians(const RoundObjectPoints& split, const Offset& offset) {
  const auto [low, high] = std::minmax_element(split.side_height.begin(), split.side_height.end());
  const double step = (*high - *low) / kProfileSlices;
  std::vector<std::vector<double>> slices(kProfileSlices);
  for (size_t i = 0; i < split.side_xy.size(); ++i) {
    const int slice = step > 0.0 ? static_cast<int>((split.side_height[i] - *low) / step) : 0;
    slices[std::clamp(slice, 0, kProfileSlices - 1)].push_back(offset(i));
  }
  std::vector<double> medians;
  for (const auto& values : slices) {
    if (static_cast<int>(values.size()) >= kMinSidePoints) medians.push_back(quantile(values, 0.5));
  }
  return medians;
}

bool taperIsStraight(const RoundObjectPoints& split, const ConeSolution& cone) {
  const Vec2d centre(cone.x[0], cone.x[1]);
  const double mean_radius = cone.x[2] + 0.5 * cone.x[3] * split.height;
  const double tolerance = std::max(kProfileFloor, kProfileTolerance * std::abs(mean_radius));
  for (double offset : sliceMedians(split, [&](size_t i) {
         return (split.side_xy[i] - centre).norm() - (cone.x[2] + cone.x[3] * split.side_height[i]);
       })) {
    if (std::abs(offset) > tolerance) return false;
  }
  return true;
}

// The body of an object narrowing upwards in steps (a bottle): a cylinder through the lower
// half of its side wall (a bottle's body is ~60 % of its height), as high as its points reach.
ShapeFit bodyCylinder(const RoundObjectPoints& split, const CylinderParams& params) {
  const auto [low, high] = std::minmax_element(split.side_height.begin(), split.side_height.end());
  const double middle = 0.5 * (*low + *high);
  const RoundObjectPoints body =
      sideWallWhere(split, [&](size_t i) { return split.side_height[i] <= middle; });
  Circle circle;
  return cylinderFromSplit(body, params, circle);
}

ShapeFit failed(ShapeType type, const std::string& reason) {
  ShapeFit fit;
  fit.type = type;
  fit.reason = reason;
  return fit;
}

}  // namespace

Circle fitCircleAlgebraic(const std::vector<Eigen::Vector2f>& points) {
  return algebraicCircle(toDouble(points));
}

float largestAngularGap(std::vector<float> angles) {
  std::sort(angles.begin(), angles.end());
  float gap = angles.front() + 2.0f * static_cast<float>(kPi) - angles.back();
  for (size_t i = 1; i < angles.size(); ++i) gap = std::max(gap, angles[i] - angles[i - 1]);
  return gap;
}

Circle refineCircleGeometric(const std::vector<Eigen::Vector2f>& points, const Circle& initial,
                             int max_iterations) {
  return geometricCircle(toDouble(points), initial, max_iterations);
}

ShapeFit fitCylinder(const NormalCloud& object, const Plane& table, const CylinderParams& params) {
  const RoundObjectPoints split = splitObject(object, table, params);
  if (!split.ok) return failed(ShapeType::Cylinder, split.reason);
  Circle circle;
  return cylinderFromSplit(split, params, circle);
}

ShapeFit fitCone(const NormalCloud& object, const Plane& table, const CylinderParams& cylinder,
                 const ConeParams& /*params*/) {
  const RoundObjectPoints split = splitObject(object, table, cylinder);
  if (!split.ok) return failed(ShapeType::Cone, split.reason);
  Circle circle;
  const ShapeFit start = cylinderFromSplit(split, cylinder, circle);
  if (!circle.ok) return failed(ShapeType::Cone, start.reason);
  ConeSolution solution;
  return coneFromSplit(split, circle, cylinder, solution);
}

ShapeFit fitRoundObject(const NormalCloud& object, const Plane& table,
                        const CylinderParams& cylinder, const ConeParams& cone) {
  const RoundObjectPoints split = splitObject(object, table, cylinder);
  if (!split.ok) return failed(ShapeType::Cylinder, split.reason);
  Circle circle;
  ShapeFit cylinder_fit = cylinderFromSplit(split, cylinder, circle);
  if (!circle.ok) return cylinder_fit;
  ConeSolution solution;
  ShapeFit cone_fit = coneFromSplit(split, circle, cylinder, solution);
  const double slope = solution.x[3];
  const bool slope_significant = std::abs(slope) >= cone.min_slope &&
                                 std::abs(slope) > cone.slope_sigma * solution.slope_stderr;
  if (!slope_significant || !taperIsMeasurable(solution, split.height) || !cone_fit.ok ||
      nearWallContradictsTaper(split, solution))
    return cylinder_fit;
  if (slope < 0.0 && !taperIsStraight(split, solution)) {
    // Not a cone: the body's cylinder, else the whole wall's.
    const ShapeFit body = bodyCylinder(split, cylinder);
    if (body.ok) return body;
    if (cylinder_fit.ok) return cylinder_fit;
  }
  return cone_fit;
}

float distanceToRoundObject(const ShapeFit& round, const Eigen::Vector3f& point) {
  // In the plane through the axis and the point, the solid is the trapezoid (0, 0), (r_bottom,
  // 0), (r_top, h), (0, h) in (distance from the axis, height); its surface is every edge but
  // the axis.
  const RoundSolid solid(round);
  const Vec3d q = solid.local(point);
  const Vec2d radial(q.head<2>().norm(), q.z());
  return static_cast<float>(
      std::min({segmentDistance(radial, Vec2d(Vec2d::Zero()), solid.bottom_rim),
                segmentDistance(radial, solid.bottom_rim, solid.top_rim),
                segmentDistance(radial, solid.top_rim, solid.top_centre)}));
}

namespace {

// What distanceToVisibleRoundSurface needs of the solid and the camera, worked out once for all
// the points measured against one solid (the residual of a fit measures every point of its
// cluster): the same operations per point as for one.
struct VisibleRoundSolid {
  explicit VisibleRoundSolid(const ShapeFit& round)
      : solid(round),
        camera(solid.local(Eigen::Vector3f::Zero())),
        slope((solid.top_rim.x() - solid.bottom_rim.x()) / solid.height) {
    // A generatrix at azimuth phi faces the camera where cos(phi - phi_camera) > (r(z) + slope
    // (z_camera - z)) / rho_camera (outward normal ~ (cos phi, sin phi, -slope)); taken half-way
    // up, which is exact for a cylinder.
    const double rho_camera = camera.head<2>().norm();
    const double bound = rho_camera > 0.0 ? (0.5 * (solid.bottom_rim.x() + solid.top_rim.x()) +
                                             slope * (camera.z() - 0.5 * solid.height)) /
                                                rho_camera
                                          : 2.0;
    wall_seen = bound < 1.0;
    if (!wall_seen) return;
    half_angle = std::acos(std::max(bound, -1.0));
    camera_azimuth = std::atan2(camera.y(), camera.x());
    camera_direction = camera.head<2>() / rho_camera;
    cos_half_angle = std::cos(half_angle);
    for (int side = 0; side < 2; ++side) {
      // The silhouette generatrix on the side of a negative (0) or positive (1) offset.
      const double azimuth = camera_azimuth + std::copysign(half_angle, side ? 1.0 : -1.0);
      const Vec3d direction(std::cos(azimuth), std::sin(azimuth), 0.0);
      silhouette_bottom[side] = solid.bottom_rim.x() * direction;
      silhouette_top[side] = solid.top_rim.x() * direction + Vec3d(0.0, 0.0, solid.height);
    }
  }

  // Infinite where no visible part is found.
  double distance(const Eigen::Vector3f& point) const {
    const Vec3d q = solid.local(point);
    const Vec2d radial(q.head<2>().norm(), q.z());
    double distance = std::numeric_limits<double>::infinity();
    if (camera.z() > solid.height) {  // the top disc faces the camera
      distance = segmentDistance(radial, solid.top_rim, solid.top_centre);
    }
    // An open container (a mug, a bowl) shows its inside over the rim: a point inside the solid
    // whose line of sight leaves through the top disc lies on the inner wall or the floor. PCL's
    // mug, seen from above, was a box without this (inside points 14 mm RMS off either model).
    const double radius_here = solid.bottom_rim.x() + slope * q.z();
    if (camera.z() > solid.height && q.z() > 0.0 && q.z() < solid.height &&
        radial.x() < radius_here) {
      const Vec3d exit = q + (solid.height - q.z()) / (camera.z() - q.z()) * (camera - q);
      if (exit.head<2>().norm() < solid.top_rim.x()) {
        distance =
            std::min({distance, segmentDistance(radial, solid.bottom_rim, solid.top_rim), q.z()});
      }
    }
    if (wall_seen) {
      bool facing = false, positive = false;
      if (!facingWithoutAngle(q, radial.x(), facing, positive)) {
        const double offset = std::remainder(std::atan2(q.y(), q.x()) - camera_azimuth, 2.0 * kPi);
        facing = std::abs(offset) <= half_angle;
        positive = !std::signbit(offset);
      }
      if (facing) {
        distance = std::min(distance, segmentDistance(radial, solid.bottom_rim, solid.top_rim));
      } else {
        // Nearest visible wall: the silhouette generatrix on the point's side.
        const int side = positive ? 1 : 0;
        distance =
            std::min(distance, segmentDistance(q, silhouette_bottom[side], silhouette_top[side]));
      }
    }
    return distance;
  }

  // Whether the point `q` (at `rho` from the axis) lies on the wall facing the camera, |offset|
  // <= half_angle for its azimuth's offset from the camera's, and if not on which side (offset
  // positive), as distance() tells from the angle, but from the cosine and sine of the offset
  // (a dot and a cross product) where they lie clear of the bounds: false where they do not
  // (and for a point on the axis, or NaN), for the angle to decide. Clear by kClear, the answers
  // are those of the angle (its rounding, atan2's and remainder's, stays below 1e-14 rad, and
  // the cosine moves no faster than the angle), for a fifteenth of the instructions.
  bool facingWithoutAngle(const Vec3d& q, double rho, bool& facing, bool& positive) const {
    constexpr double kClear = 1e-7;
    if (!(rho > 1e-9)) return false;
    const double along = q.x() * camera_direction.x() + q.y() * camera_direction.y();
    if (along > (cos_half_angle + kClear) * rho) {
      facing = true;
      return true;
    }
    const double across = camera_direction.x() * q.y() - camera_direction.y() * q.x();
    if (along < (cos_half_angle - kClear) * rho && std::abs(across) > kClear * rho) {
      facing = false;
      positive = across > 0.0;
      return true;
    }
    return false;
  }

  RoundSolid solid;
  Vec3d camera;
  double slope;
  bool wall_seen = false;
  double half_angle = 0.0, camera_azimuth = 0.0;
  Vec2d camera_direction = Vec2d::Zero();  // (cos, sin) of camera_azimuth
  double cos_half_angle = 1.0;
  Vec3d silhouette_bottom[2], silhouette_top[2];
};

}  // namespace

float distanceToVisibleRoundSurface(const ShapeFit& round, const Eigen::Vector3f& point) {
  const double distance = VisibleRoundSolid(round).distance(point);
  return std::isfinite(distance) ? static_cast<float>(distance)
                                 : distanceToRoundObject(round, point);
}

void distancesToVisibleRoundSurface(const ShapeFit& round, const NormalCloud& points,
                                    std::vector<float>& distances) {
  const VisibleRoundSolid visible(round);
  distances.clear();
  distances.reserve(points.size());
  for (const auto& p : points.points) {
    const double distance = visible.distance(p.getVector3fMap());
    distances.push_back(std::isfinite(distance) ? static_cast<float>(distance)
                                                : distanceToRoundObject(round, p.getVector3fMap()));
  }
}

// ---- a cylinder lying on its side (beyond the paper) ----
namespace {

// A side-wall normal of a lying cylinder is perpendicular to its axis; an end disc's is along it.
// Points whose normal is within 60 degrees of the axis belong to an end disc.
const double kEndDiscMinCos = 0.5;
// A lying solid may sink into the table by the wall's noise, not more: 3 trimmed RMS, at least
// this much (a real can cannot pass through the table it lies on).
constexpr double kMaxBelowTable = 0.005;  // [m]
// Start axes fitted in full, the most circular sections first (sectionSpread).
constexpr size_t kFullyFittedAxes = 2;

// The points seen along the horizontal `axis` of a lying cylinder: the side-wall points in the
// vertical plane across the axis (s along up x axis, h above the table), every point's and the
// end disc's coordinates along it. `table_d` is the table's d for the unit `up`.
struct LyingSection {
  Vec3d axis, across;
  std::vector<Vec2d> section;
  std::vector<double> along, end_disc;
};

// `heights`: each point's up.dot(position) + table_d, the same along every axis.
LyingSection sectionAcross(const Vec3d& axis, const Vec3d& up, const std::vector<Vec3d>& positions,
                           const std::vector<Vec3d>& normals, const std::vector<double>& heights) {
  LyingSection out;
  out.axis = axis;
  out.across = up.cross(axis);
  out.along.resize(positions.size());
  out.section.reserve(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    out.along[i] = axis.dot(positions[i]);
    const double along_normal = normals[i].dot(axis);
    if (along_normal >= kEndDiscMinCos) out.end_disc.push_back(out.along[i]);
    if (std::abs(along_normal) >= kEndDiscMinCos) continue;
    out.section.emplace_back(out.across.dot(positions[i]), heights[i]);
  }
  return out;
}

// How far the side-wall section strays from a circle, cheaply: the median distance of its
// points from their algebraic circle (infinite without one). A start axis a few degrees off
// smears the section into an ellipse; this ranks the start axes so that only the most circular
// sections get the trimmed geometric fit, which costs ~50 times more.
double sectionSpread(const LyingSection& lying) {
  if (static_cast<int>(lying.section.size()) < kMinSidePoints) {
    return std::numeric_limits<double>::infinity();
  }
  const Circle circle = algebraicCircle(lying.section);
  if (!circle.ok) return std::numeric_limits<double>::infinity();
  std::vector<double> distances(lying.section.size());
  for (size_t i = 0; i < lying.section.size(); ++i) {
    distances[i] =
        std::abs((lying.section[i] - circle.center.cast<double>()).norm() - circle.radius);
  }
  return quantile(std::move(distances), 0.5);
}

// The cylinder lying along the section's axis: a circle through the side-wall points across
// it; its length the points' extent along the axis.
ShapeFit lyingCylinderAlong(const LyingSection& lying, const Vec3d& up, double table_d,
                            const CylinderParams& params) {
  ShapeFit fit;
  fit.type = ShapeType::Cylinder;
  const Vec3d& axis = lying.axis;
  const Vec3d& across = lying.across;
  const std::vector<Vec2d>& section = lying.section;
  const std::vector<double>& along = lying.along;
  const std::vector<double>& end_disc = lying.end_disc;
  if (static_cast<int>(section.size()) < kMinSidePoints) {
    fit.reason = "too few side-wall points (" + std::to_string(section.size()) + ")";
    return fit;
  }
  const Circle initial = algebraicCircle(section);
  if (!initial.ok) {
    fit.reason = "side-wall points are collinear across the axis (no circle)";
    return fit;
  }
  const TrimmedSolution trimmed = trimmedLeastSquares(
      RoundWallResiduals{section},
      Eigen::Vector3d(initial.center.x(), initial.center.y(), initial.radius),
      static_cast<int>(section.size()), std::max(0, params.max_refine_iterations));
  const double radius = std::abs(trimmed.x[2]);
  // The end facing the camera like an upright cylinder's top: from its disc when seen (a real
  // tin on its rim, its disc a degree or two off square to the fitted axis, spread 8 cm along
  // it), else from the wall.
  const double low = quantile(along, 1.0 - kHeightQuantile),
               high = static_cast<int>(end_disc.size()) >= kMinTopPoints
                          ? topHeight(end_disc)
                          : quantile(along, kHeightQuantile);
  fit.radius = static_cast<float>(radius);
  fit.height = static_cast<float>(high - low);
  fit.points = trimmed.inlier_count;
  fit.rmse = static_cast<float>(trimmed.rmse);
  // z along the axis, x up: x cross y = up cross (axis cross up) = axis.
  Eigen::Matrix3d rotation;
  rotation.col(0) = up;
  rotation.col(1) = axis.cross(up);
  rotation.col(2) = axis;
  fit.orientation = Eigen::Quaternionf(rotation.cast<float>()).normalized();
  fit.center = (0.5 * (low + high) * axis + trimmed.x[0] * across + (trimmed.x[1] - table_d) * up)
                   .cast<float>();
  const double bottom = trimmed.x[1] - radius;
  if (!trimmed.x.allFinite()) {
    fit.reason = "circle refinement across the axis diverged";
  } else if (!radiusInBounds(radius, params)) {
    fit.reason = formatRadius("lying radius", radius, params);
  } else if (bottom < -std::max(kMaxBelowTable, 3.0 * trimmed.rmse)) {
    std::ostringstream reason;
    reason << "lying cylinder reaches " << -bottom << " m below the table";
    fit.reason = reason.str();
  } else {
    fit.ok = keepsEnoughPoints(trimmed.inlier_count, section.size(), fit);
  }
  return fit;
}

// The horizontal direction most nearly perpendicular to the side-wall normals (those not
// within kEndDiscMinCos of `axis`): a start axis tilted by an end disc's normals or by the
// footprint's proportions, made the wall's own. Three rounds settle it to a degree or better.
// `horizontals`: each normal's coordinates along e1 = up.unitOrthogonal() and e2 = up x e1.
Vec3d sideWallAxis(Vec3d axis, const Vec3d& up, const std::vector<Vec3d>& normals,
                   const std::vector<Vec2d>& horizontals) {
  const Vec3d e1 = up.unitOrthogonal(), e2 = up.cross(e1);
  for (int round = 0; round < 3; ++round) {
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    int side = 0;
    for (size_t i = 0; i < normals.size(); ++i) {
      if (std::abs(normals[i].dot(axis)) >= kEndDiscMinCos) continue;
      scatter += horizontals[i] * horizontals[i].transpose();
      ++side;
    }
    if (side < kMinSidePoints) break;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> principal(scatter);
    const Vec2d smallest = principal.eigenvectors().col(0);
    const Vec3d next = (smallest.x() * e1 + smallest.y() * e2).normalized();
    axis = next.dot(axis) < 0.0 ? Vec3d(-next) : next;
  }
  return axis;
}

}  // namespace

ShapeFit fitLyingCylinder(const NormalCloud& object, const Plane& table,
                          const CylinderParams& params) {
  const double normal_length = table.normal.cast<double>().norm();
  if (!std::isfinite(normal_length) || !std::isfinite(table.d) || normal_length < 1e-6) {
    return failed(ShapeType::Cylinder, "invalid table plane");
  }
  const Vec3d up = table.normal.cast<double>() / normal_length;
  const double table_d = table.d / normal_length;
  std::vector<Vec3d> positions, normals;
  positions.reserve(object.size());
  normals.reserve(object.size());
  Vec3d centroid = Vec3d::Zero();
  // Axis candidates, horizontal: the principal directions of the normals' horizontal parts
  // (across the axis on the side wall, along it on an end disc) and of the points' footprint
  // (along the axis when longer than wide, across it for a tin on its rim). Which one is the
  // axis depends on the view and the proportions, and smoothed normals on a can 7 cm across
  // tilt it by 10-20 degrees (a real lying can's circle then came out 3 times too large).
  Eigen::Matrix3d normal_scatter = Eigen::Matrix3d::Zero(), point_scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : object.points) {
    const Vec3d position(p.x, p.y, p.z), normal(p.normal_x, p.normal_y, p.normal_z);
    if (!position.allFinite() || !normal.allFinite() || !(normal.norm() > 0.0)) continue;
    positions.push_back(position);
    normals.push_back(normal.normalized());
    centroid += position;
    const Vec3d horizontal = normals.back() - normals.back().dot(up) * up;
    normal_scatter += horizontal * horizontal.transpose();
  }
  if (static_cast<int>(positions.size()) < kMinSidePoints) {
    return failed(ShapeType::Cylinder,
                  "too few points with a normal (" + std::to_string(positions.size()) + ")");
  }
  centroid /= static_cast<double>(positions.size());
  for (const Vec3d& position : positions) {
    const Vec3d offset = position - centroid;
    point_scatter += offset * offset.transpose();
  }
  const Vec3d e1 = up.unitOrthogonal(), e2 = up.cross(e1);
  // What every start axis's section and refinement reads of each point alike.
  std::vector<double> heights(positions.size());
  std::vector<Vec2d> horizontals(normals.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    heights[i] = up.dot(positions[i]) + table_d;
    horizontals[i] = Vec2d(normals[i].dot(e1), normals[i].dot(e2));
  }
  // Each start axis and its side-wall refinement: smoothed normals near an occluding edge pull
  // the refinement off by a few degrees too (on a real can 23 cm long, 3.7 degrees smeared its
  // section 4 mm RMS), so the circle that follows its side wall most closely decides.
  std::vector<Vec3d> tried;
  std::vector<std::pair<double, LyingSection>> sections;  // (sectionSpread, section)
  auto tryAxis = [&](Vec3d axis) {
    for (const Vec3d& other : tried) {
      if (std::abs(other.dot(axis)) > std::cos(kPi / 180.0)) return;  // within a degree
    }
    tried.push_back(axis);
    // The axis points towards the camera (the origin), so the end disc the camera may see is
    // the solid's "top" (distanceToVisibleRoundSurface).
    if (axis.dot(-centroid) < 0.0) axis = -axis;
    LyingSection lying = sectionAcross(axis, up, positions, normals, heights);
    const double spread = sectionSpread(lying);
    sections.emplace_back(spread, std::move(lying));
  };
  for (const Eigen::Matrix3d* scatter : {&normal_scatter, &point_scatter}) {
    Eigen::Matrix2d planar;
    planar << e1.dot(*scatter * e1), e1.dot(*scatter * e2), e2.dot(*scatter * e1),
        e2.dot(*scatter * e2);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> principal(planar);
    for (int k = 0; k < 2; ++k) {
      const Vec3d start =
          (principal.eigenvectors()(0, k) * e1 + principal.eigenvectors()(1, k) * e2).normalized();
      tryAxis(start);
      tryAxis(sideWallAxis(start, up, normals, horizontals));
    }
  }
  // The most circular sections get the full fit; of those that fit, the one that follows its
  // side wall most closely wins.
  std::stable_sort(sections.begin(), sections.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  ShapeFit best;
  for (size_t i = 0; i < std::min(sections.size(), kFullyFittedAxes); ++i) {
    ShapeFit fit = lyingCylinderAlong(sections[i].second, up, table_d, params);
    const bool better = fit.ok ? !best.ok || fit.rmse < best.rmse : !best.ok && best.reason.empty();
    if (better) best = fit;
  }
  return best;
}

}  // namespace tabletop_shapes
