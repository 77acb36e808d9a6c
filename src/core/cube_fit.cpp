#include "tabletop_shapes/core/cube_fit.h"

#include "tabletop_shapes/core/plane_support.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <optional>
#include <queue>
#include <random>

namespace tabletop_shapes {
namespace {

constexpr int kMinPoints = 30;
// Box faces meet at right angles: a chosen plane must be within this of perpendicular to the
// other chosen planes, and within it of parallel or perpendicular to the table.
constexpr float kRightAngleTolerance = static_cast<float>(kPi / 6);
// Ends of the box not bounded by a seen face come from the point coordinates, ignoring this
// fraction of the points at each end (flying pixels); an edge row of a face holds more.
constexpr float kExtentOutlierFraction = 0.01f;
constexpr int kRefineIterations = 3;
constexpr int kMaxSampleTries = 20;
// Hypotheses are scored on a random subset of this many points (the chosen planes are then
// refined on all of them): the ranking needs fractions and mean angles, not every point.
constexpr int kScoringPoints = 1000;        // draws for a second / third point sharing the normal
constexpr unsigned kRandomSeed = 20120715;  // fixed: the same cloud gives the same box

struct Candidate {
  Eigen::Vector3f normal;
  float d = 0.0f;
  // Mean angle between the support's point normals and the plane's; until `exact`, a lower
  // bound of it (PlaneSupport::countWithAngleBound).
  float mean_angle = 0.0f;
  int support = 0;
  bool exact = false;
};

struct Face {
  Eigen::Vector3f normal;  // outward, i.e. towards the camera like the point normals
  float d = 0.0f;
  std::vector<int> support;
  int axis = -1;  // box axis the face is perpendicular to (0, 1: vertical faces, 2: top)
  int side = 0;   // +1: the face bounds the box at the positive end of its axis, -1: negative
};

// Scatter matrix of the points `indices` (not empty) of `cloud` about their `mean`.
Eigen::Matrix3d scatterOf(const NormalCloud& cloud, const std::vector<int>& indices,
                          Eigen::Vector3d& mean) {
  mean = Eigen::Vector3d::Zero();
  for (int i : indices) mean += cloud[i].getVector3fMap().cast<double>();
  mean /= static_cast<double>(indices.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (int i : indices) {
    const Eigen::Vector3d q = cloud[i].getVector3fMap().cast<double>() - mean;
    scatter += q * q.transpose();
  }
  return scatter;
}

// Total least squares plane of the support (eigenvector of the smallest eigenvalue of the
// scatter): the OLS of eq. 4-8 on the orthogonal distance, free of its d = 0 special case.
// Keeps the sign of `normal`. Returns false for fewer than 3 or collinear points.
bool fitPlane(const NormalCloud& cloud, const std::vector<int>& indices, Eigen::Vector3f& normal,
              float& d) {
  if (indices.size() < 3) return false;
  Eigen::Vector3d mean;
  const Eigen::Matrix3d scatter = scatterOf(cloud, indices, mean);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::Vector3d eigenvalues = solver.eigenvalues();                    // ascending
  if (eigenvalues(1) <= 1e-9 * std::max(eigenvalues(2), 1e-12)) return false;  // collinear
  Eigen::Vector3f fitted = solver.eigenvectors().col(0).cast<float>().normalized();
  if (fitted.dot(normal) < 0.0f) fitted = -fitted;
  normal = fitted;
  d = -normal.dot(mean.cast<float>());
  return true;
}

// Refits the plane on its support and re-collects the support, a few times (a RANSAC plane
// from 3 noisy points is tilted; its refined support spans the whole face). The normal is then
// oriented like the point normals of its support (outward for a visible face).
bool refineFace(const NormalCloud& cloud, PlaneSupport& all, const CubeParams& params, Face& face) {
  // Inliers (§3.2): distance below the threshold AND point normal within the angular threshold
  // of the plane normal (either sign: RANSAC planes are unoriented).
  const float cos_threshold = std::cos(params.angle_threshold);
  // A refit that returns the plane it started from, to the bit, settles it: every later round
  // would collect the same support and return the same plane again, and the support already
  // collected is the final one.
  bool settled = false;
  for (int iteration = 0; iteration < kRefineIterations && !settled; ++iteration) {
    face.support.clear();
    all.collect(face.normal, face.d, params.distance_threshold, cos_threshold, &face.support,
                nullptr);
    const float before[4] = {face.normal.x(), face.normal.y(), face.normal.z(), face.d};
    if (!fitPlane(cloud, face.support, face.normal, face.d)) return false;
    const float after[4] = {face.normal.x(), face.normal.y(), face.normal.z(), face.d};
    settled = std::memcmp(before, after, sizeof before) == 0;
  }
  if (!settled) {
    face.support.clear();
    all.collect(face.normal, face.d, params.distance_threshold, cos_threshold, &face.support,
                nullptr);
  }
  float agreement = 0.0f;
  for (int i : face.support) agreement += face.normal.dot(cloud[i].getNormalVector3fMap());
  if (agreement < 0.0f) {
    face.normal = -face.normal;
    face.d = -face.d;
  }
  return face.support.size() >= 3;
}

// A face's support must spread at least this much (RMS) along both of its in-plane directions.
// Where the image border cuts a box seen steeply from above, the part of a side face still in
// view is a strip along the border: on a RealSense border box at 0.36 m, 34 points 3.2 mm RMS
// across (13.6 along), whose plane's tilt about the strip is unmeasured; its normal turned the
// box 7 degrees and made it 47 mm thick for 38. A box's faces (>= 2 cm) spread 6 mm RMS and more.
constexpr double kMinFaceSpread = 0.004;  // [m]

// True when the points `indices` of `cloud` spread at least kMinFaceSpread along both directions
// of their plane (the scatter's two larger principal axes).
bool spreadsAsAFace(const NormalCloud& cloud, const std::vector<int>& indices) {
  if (indices.size() < 3) return false;
  Eigen::Vector3d mean;
  const Eigen::Matrix3d scatter = scatterOf(cloud, indices, mean);
  const Eigen::Vector3d eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter, Eigen::EigenvaluesOnly).eigenvalues();
  return eigenvalues(1) / static_cast<double>(indices.size()) >= kMinFaceSpread * kMinFaceSpread;
}

bool isHorizontal(const Eigen::Vector3f& normal, const Eigen::Vector3f& up) {
  return std::abs(normal.dot(up)) > std::cos(kRightAngleTolerance);
}
bool isVertical(const Eigen::Vector3f& normal, const Eigen::Vector3f& up) {
  return std::abs(normal.dot(up)) < std::sin(kRightAngleTolerance);
}

// A plane joins the chosen ones if it is not a duplicate (the paper: normals at least
// min_plane_angle apart), is roughly perpendicular to each (a box), and is parallel or
// perpendicular to the table (the box stands on it).
bool consistentPlane(const Eigen::Vector3f& normal, const std::vector<Face>& chosen,
                     const Eigen::Vector3f& up, const CubeParams& params) {
  if (!isHorizontal(normal, up) && !isVertical(normal, up)) return false;
  for (const Face& face : chosen) {
    const float cosine = std::abs(normal.dot(face.normal));
    if (cosine > std::cos(params.min_plane_angle)) return false;  // the same face again
    if (cosine > std::sin(kRightAngleTolerance)) return false;    // not perpendicular
  }
  return true;
}

// How far the hidden end facing `outward` moves in for the edge smear: none where the image
// border cut the object (a cut direction within ~73 degrees of it).
float smearAt(const Eigen::Vector3f& outward, const SilhouetteSmear& smear) {
  for (const Eigen::Vector3f& d : smear.cut_directions) {
    if (d.dot(outward) > 0.3f) return 0.0f;
  }
  return smear.distance;
}

// Direction (unit) of the minimum-area rectangle enclosing 2-D points: rotating calipers over
// their convex hull.
Eigen::Vector2f minimumAreaRectangleDirection(std::vector<Eigen::Vector2f> points) {
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  auto cross = [](const Eigen::Vector2f& o, const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
    return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
  };
  // Andrew's monotone chain.
  std::vector<Eigen::Vector2f> hull(2 * points.size());
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k > 1 ? k - 1 : k);

  Eigen::Vector2f best_direction(1.0f, 0.0f);
  float best_area = std::numeric_limits<float>::max();
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f edge = hull[(i + 1) % hull.size()] - hull[i];
    if (edge.norm() < 1e-6f) continue;
    const Eigen::Vector2f u = edge.normalized(), v(-u.y(), u.x());
    float u_min = std::numeric_limits<float>::max(), u_max = -u_min;
    float v_min = u_min, v_max = -u_min;
    for (const auto& q : hull) {
      u_min = std::min(u_min, q.dot(u));
      u_max = std::max(u_max, q.dot(u));
      v_min = std::min(v_min, q.dot(v));
      v_max = std::max(v_max, q.dot(v));
    }
    const float area = (u_max - u_min) * (v_max - v_min);
    if (area < best_area) {
      best_area = area;
      best_direction = u;
    }
  }
  return best_direction;
}

// The same for the points `indices` of `cloud` projected on the plane spanned by e1, e2; the
// direction in 3-D.
template <typename CloudT>
Eigen::Vector3f minimumAreaRectangleAxis(const CloudT& cloud, const std::vector<int>& indices,
                                         const Eigen::Vector3f& e1, const Eigen::Vector3f& e2) {
  std::vector<Eigen::Vector2f> points;
  points.reserve(indices.size());
  for (int i : indices) {
    const Eigen::Vector3f p = cloud[i].getVector3fMap();
    points.emplace_back(p.dot(e1), p.dot(e2));
  }
  const Eigen::Vector2f direction = minimumAreaRectangleDirection(std::move(points));
  return (direction.x() * e1 + direction.y() * e2).normalized();
}

ShapeFit failure(ShapeFit fit, const std::string& reason) {
  fit.ok = false;
  fit.reason = reason;
  return fit;
}

// Orientation and dimensions of a box with edges `dimensions` along the columns of `axes` (z =
// up), made canonical: x along the longer horizontal edge (right-handed, z stays up).
void setBoxPose(Eigen::Matrix3f axes, Eigen::Vector3f dimensions, ShapeFit& fit) {
  if (dimensions.y() > dimensions.x()) {
    const Eigen::Vector3f x_axis = axes.col(0);
    axes.col(0) = axes.col(1);
    axes.col(1) = -x_axis;
    std::swap(dimensions.x(), dimensions.y());
  }
  fit.orientation = Eigen::Quaternionf(axes).normalized();
  fit.dimensions = dimensions;
}

// RMS distance of all the points of `cloud` to the surface of the box `fit`.
template <typename CloudT>
float rmsDistanceToBox(const ShapeFit& fit, const CloudT& cloud) {
  double squared_sum = 0.0;
  for (const auto& p : cloud.points) {
    const float distance = distanceToBox(fit, p.getVector3fMap());
    squared_sum += static_cast<double>(distance) * distance;
  }
  return cloud.empty() ? 0.0f : static_cast<float>(std::sqrt(squared_sum / cloud.size()));
}

}  // namespace

float quantile(std::vector<float>& values, float fraction) {
  const size_t index = std::min(values.size() - 1,
                                static_cast<size_t>(fraction * static_cast<float>(values.size())));
  std::nth_element(values.begin(), values.begin() + index, values.end());
  return values[index];
}

ShapeFit fitCube(const NormalCloud& object, const Plane& table, const CubeParams& params,
                 const SilhouetteSmear& smear) {
  ShapeFit fit;
  fit.type = ShapeType::Cube;
  const int n = static_cast<int>(object.size());
  fit.points = n;
  if (n < kMinPoints) {
    return failure(fit, "too few points for a box fit (" + std::to_string(n) + " < " +
                            std::to_string(kMinPoints) + ")");
  }
  const float table_norm = table.normal.norm();
  if (!std::isfinite(table_norm) || table_norm < 1e-6f || !std::isfinite(table.d)) {
    return failure(fit, "invalid table plane");
  }
  const Eigen::Vector3f up = table.normal / table_norm;
  const float table_d = table.d / table_norm;

  // ---- RANSAC (§3.2): 3 points -> plane, inliers by distance and normal angle ----
  // Sampling is guided: the 2nd and 3rd points are drawn among points whose normal agrees with
  // the 1st one's, so the three usually lie on one face even when it holds few of the points.
  const float cos_threshold = std::cos(params.angle_threshold);
  const int min_support = std::max(3, static_cast<int>(std::ceil(params.min_support_fraction * n)));
  std::mt19937 rng(kRandomSeed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<int> all(n);
  std::iota(all.begin(), all.end(), 0);
  std::vector<int> scoring = all;
  if (n > kScoringPoints) {
    for (int i = 0; i < kScoringPoints; ++i) {
      std::swap(scoring[i], scoring[std::uniform_int_distribution<int>(i, n - 1)(rng)]);
    }
    scoring.resize(kScoringPoints);
  }
  const int min_scoring_support =
      std::max(3, static_cast<int>(std::ceil(params.min_support_fraction * scoring.size())));
  PlaneSupport scoring_points(object, scoring);
  auto drawAgreeing = [&](const Eigen::Vector3f& normal, int a, int b) {
    for (int attempt = 0; attempt < kMaxSampleTries; ++attempt) {
      const int j = pick(rng);
      if (j != a && j != b &&
          std::abs(normal.dot(object[j].getNormalVector3fMap())) > cos_threshold) {
        return j;
      }
    }
    return -1;
  };
  // The queue ranks planes by their mean angles, but only the planes a box can still take need
  // theirs exactly: a plane leaves the queue by its lower bound, and gets its exact mean angle
  // and goes back in when the chosen planes still admit it. Once the top is exact it is the
  // lowest mean angle left, so the planes are taken as by their exact mean angles alone (the
  // acos of every inlier of ~250 planes per box cost 3.5 M instructions per object).
  auto exactMeanAngle = [&](Candidate& candidate) {
    double angle_sum = 0.0;
    scoring_points.collect(candidate.normal, candidate.d, params.distance_threshold, cos_threshold,
                           nullptr, &angle_sum, min_scoring_support);
    candidate.mean_angle = static_cast<float>(angle_sum / candidate.support);
    candidate.exact = true;
  };
  auto byMeanAngle = [](const Candidate& a, const Candidate& b) {
    return a.mean_angle > b.mean_angle;  // top of the queue: the lowest mean angle
  };
  std::priority_queue<Candidate, std::vector<Candidate>, decltype(byMeanAngle)> queue(byMeanAngle);
  for (int iteration = 0; iteration < params.ransac_iterations; ++iteration) {
    const int i0 = pick(rng);
    const Eigen::Vector3f n0 = object[i0].getNormalVector3fMap();
    const int i1 = drawAgreeing(n0, i0, i0);
    const int i2 = i1 < 0 ? -1 : drawAgreeing(n0, i0, i1);
    if (i2 < 0) continue;
    const Eigen::Vector3f p0 = object[i0].getVector3fMap();
    Eigen::Vector3f normal =
        (object[i1].getVector3fMap() - p0).cross(object[i2].getVector3fMap() - p0);
    if (normal.norm() < 1e-6f) continue;  // (nearly) collinear sample
    normal.normalize();
    // A plane disagreeing with its own sample's normals cannot gather a consistent support.
    if (std::abs(normal.dot(n0)) <= cos_threshold) continue;
    const float d = -normal.dot(p0);
    double angle_bound = 0.0;
    const int support = scoring_points.countWithAngleBound(normal, d, params.distance_threshold,
                                                           cos_threshold, angle_bound);
    if (support < min_scoring_support) continue;
    Candidate candidate{normal, d, static_cast<float>(angle_bound / support), support};
    if (!std::isfinite(candidate.mean_angle)) exactMeanAngle(candidate);
    queue.push(candidate);
  }
  if (queue.empty()) {
    return failure(fit, "no plane with at least " +
                            std::to_string(static_cast<int>(params.min_support_fraction * 100)) +
                            " % of the points");
  }

  // ---- pop planes by mean angular distance; keep distinct, mutually perpendicular ones ----
  std::vector<Face> faces;
  // With at most kScoringPoints the scoring points are all the points, in their order: their
  // PlaneSupport serves (each collect writes all the state it reads).
  std::optional<PlaneSupport> all_points_of_their_own;
  if (scoring.size() < all.size()) all_points_of_their_own.emplace(object, all);
  PlaneSupport& all_points = all_points_of_their_own ? *all_points_of_their_own : scoring_points;
  const int max_planes = std::clamp(params.max_planes, 1, 3);
  while (!queue.empty() && static_cast<int>(faces.size()) < max_planes) {
    Candidate candidate = queue.top();
    queue.pop();
    if (!consistentPlane(candidate.normal, faces, up, params)) continue;
    if (!candidate.exact) {
      exactMeanAngle(candidate);
      queue.push(candidate);
      continue;
    }
    Face face;
    face.normal = candidate.normal;
    face.d = candidate.d;
    if (!refineFace(object, all_points, params, face)) continue;
    if (static_cast<int>(face.support.size()) < min_support) continue;
    if (!consistentPlane(face.normal, faces, up, params)) continue;
    faces.push_back(std::move(face));
  }
  // With the top face in view of a box the image border cut (`smear.cut_directions`), its outline
  // gives the yaw: a side face seen as a strip along the cut (spreadsAsAFace) is not used.
  const bool top_seen = std::any_of(
      faces.begin(), faces.end(), [&](const Face& face) { return isHorizontal(face.normal, up); });
  if (top_seen && !smear.cut_directions.empty()) {
    faces.erase(std::remove_if(faces.begin(), faces.end(),
                               [&](const Face& face) {
                                 return !isHorizontal(face.normal, up) &&
                                        !spreadsAsAFace(object, face.support);
                               }),
                faces.end());
  }
  if (faces.empty()) return failure(fit, "no plane consistent with a box standing on the table");
  fit.faces_seen = static_cast<int>(faces.size());

  // ---- box frame: z = table normal; vertical faces snapped perpendicular to it ----
  const Face* top = nullptr;
  std::vector<const Face*> sides;
  for (const Face& face : faces) {
    if (isHorizontal(face.normal, up)) {
      if (face.normal.dot(up) < 0.0f) return failure(fit, "a horizontal face looks downwards");
      top = &face;
    } else {
      sides.push_back(&face);
    }
  }
  if (!top && sides.size() == 1) {
    return failure(fit, "only one vertical face seen: the depth of the box is not observable");
  }
  auto horizontal = [&up](const Eigen::Vector3f& v) { return (v - v.dot(up) * up).normalized(); };
  Eigen::Vector3f x_axis;
  if (sides.empty()) {
    // Seen from above: the yaw from the top face's outline (the paper fails here, pn = 1).
    const Eigen::Vector3f e1 = up.unitOrthogonal(), e2 = up.cross(e1);
    x_axis = minimumAreaRectangleAxis(object, top->support, e1, e2);
  } else {
    x_axis = horizontal(sides[0]->normal);
    if (sides.size() == 2) {
      // The orthonormal pair closest to both faces' normals, weighted by support size.
      Eigen::Vector3f turned = up.cross(horizontal(sides[1]->normal));
      if (turned.dot(x_axis) < 0.0f) turned = -turned;
      x_axis = (static_cast<float>(sides[0]->support.size()) * x_axis +
                static_cast<float>(sides[1]->support.size()) * turned)
                   .normalized();
    }
  }
  x_axis = horizontal(x_axis);
  const Eigen::Vector3f y_axis = up.cross(x_axis);
  Eigen::Matrix3f axes;
  axes << x_axis, y_axis, up;

  // Box coordinates: origin on the table under the object's centroid.
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  for (const auto& p : object.points) centroid += p.getVector3fMap();
  centroid /= static_cast<float>(n);
  const Eigen::Vector3f origin = centroid - (up.dot(centroid) + table_d) * up;
  std::vector<float> coordinates[3];
  for (auto& c : coordinates) c.reserve(n);
  for (const auto& p : object.points) {
    const Eigen::Vector3f local = axes.transpose() * (p.getVector3fMap() - origin);
    for (int a = 0; a < 3; ++a) coordinates[a].push_back(local[a]);
  }

  // ---- extents: a seen face bounds its end at the mean position of its support; the other
  // ends (hidden faces) come from the far edges of the seen faces; the bottom is the table ----
  float low[3], high[3];
  bool low_known[3] = {false, false, true}, high_known[3] = {false, false, false};
  low[2] = 0.0f;
  for (Face& face : faces) {
    const Eigen::Vector3f local_normal = axes.transpose() * face.normal;
    local_normal.cwiseAbs().maxCoeff(&face.axis);
    face.side = local_normal[face.axis] > 0.0f ? 1 : -1;
    double sum = 0.0;
    for (int i : face.support) sum += coordinates[face.axis][i];
    const float position = static_cast<float>(sum / static_cast<double>(face.support.size()));
    if (face.side > 0) {
      if (high_known[face.axis]) return failure(fit, "inconsistent planes (two on one side)");
      high[face.axis] = position;
      high_known[face.axis] = true;
    } else {
      if (low_known[face.axis]) return failure(fit, "inconsistent planes (two on one side)");
      low[face.axis] = position;
      low_known[face.axis] = true;
    }
  }
  // Hidden ends from the seen faces' support only: the other cluster points include flying
  // pixels at the box's depth edges, which reach beyond the far edge (by 1-3 cm on the paper's
  // 5 cm milk-tea box in rendered Kinect scenes).
  std::vector<char> on_face(n, 0);
  for (const Face& face : faces) {
    for (int i : face.support) on_face[i] = 1;
  }
  // Only the top face seen (a box seen from nearly straight above): its rim, the silhouette
  // over the table far below on every side, gives every end of the footprint, each smeared
  // outward. With a side face seen, the hidden ends' smear stays within ~3 mm (8.9 x 3.8 cm
  // boxes on the RealSense renders came out 2-3 mm long) and the rounded edges of flat
  // bottles end their points that much inside their box: no inset there.
  const SilhouetteSmear no_smear;
  const SilhouetteSmear& end_smear =
      faces.size() == 1 && faces.front().axis == 2 ? smear : no_smear;
  std::vector<float> face_coordinates;
  face_coordinates.reserve(n);
  for (int a = 0; a < 3; ++a) {
    if (low_known[a] && high_known[a]) continue;
    face_coordinates.clear();
    for (int i = 0; i < n; ++i) {
      if (on_face[i]) face_coordinates.push_back(coordinates[a][i]);
    }
    if (!low_known[a]) {
      low[a] =
          quantile(face_coordinates, kExtentOutlierFraction) + smearAt(-axes.col(a), end_smear);
    }
    if (!high_known[a]) {
      high[a] = quantile(face_coordinates, 1.0f - kExtentOutlierFraction) -
                smearAt(axes.col(a), end_smear);
    }
  }
  Eigen::Vector3f dimensions(high[0] - low[0], high[1] - low[1], high[2] - low[2]);
  if (!(dimensions.minCoeff() > 1e-3f) || !dimensions.allFinite()) {
    return failure(fit, "degenerate box extents");
  }
  const Eigen::Vector3f local_center(0.5f * (low[0] + high[0]), 0.5f * (low[1] + high[1]),
                                     0.5f * dimensions.z());
  fit.center = origin + axes * local_center;

  setBoxPose(axes, dimensions, fit);
  fit.rmse = rmsDistanceToBox(fit, object);
  fit.ok = true;
  return fit;
}

ShapeFit boundingBox(const Cloud& cluster, const Plane& table) {
  ShapeFit fit;
  fit.type = ShapeType::Cube;
  fit.bounding_box = true;
  const float table_norm = table.normal.norm();
  if (!std::isfinite(table_norm) || table_norm < 1e-6f || !std::isfinite(table.d)) {
    return failure(fit, "invalid table plane");
  }
  const Eigen::Vector3f up = table.normal / table_norm;
  const float table_d = table.d / table_norm;
  const Eigen::Vector3f e1 = up.unitOrthogonal(), e2 = up.cross(e1);
  std::vector<int> finite;
  float top = 0.0f;
  for (int i = 0; i < static_cast<int>(cluster.size()); ++i) {
    const Eigen::Vector3f p = cluster[i].getVector3fMap();
    if (!p.allFinite()) continue;
    finite.push_back(i);
    top = std::max(top, up.dot(p) + table_d);
  }
  fit.points = static_cast<int>(finite.size());
  if (finite.size() < 3) return failure(fit, "too few points for a bounding box");
  const Eigen::Vector3f x_axis = minimumAreaRectangleAxis(cluster, finite, e1, e2);
  const Eigen::Vector3f y_axis = up.cross(x_axis);
  Eigen::Matrix3f axes;
  axes << x_axis, y_axis, up;
  Eigen::Vector2f low = Eigen::Vector2f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector2f high = -low;
  for (int i : finite) {
    const Eigen::Vector3f p = cluster[i].getVector3fMap();
    const Eigen::Vector2f q(p.dot(x_axis), p.dot(y_axis));
    low = low.cwiseMin(q);
    high = high.cwiseMax(q);
  }
  // The box stands on the table (the points start above table.min_height) and ends at the top
  // point; no edge thinner than a millimetre, so that it stays a solid.
  Eigen::Vector3f dimensions(high.x() - low.x(), high.y() - low.y(), top);
  dimensions = dimensions.cwiseMax(1e-3f);
  const Eigen::Vector2f middle = 0.5f * (low + high);
  fit.center = middle.x() * x_axis + middle.y() * y_axis - table_d * up + 0.5f * top * up;
  setBoxPose(axes, dimensions, fit);
  fit.rmse = rmsDistanceToBox(fit, cluster);
  fit.ok = true;
  return fit;
}

float distanceToBox(const ShapeFit& box, const Eigen::Vector3f& point) {
  const Eigen::Vector3f local = box.orientation.conjugate() * (point - box.center);
  const Eigen::Vector3f outside = local.cwiseAbs() - 0.5f * box.dimensions;
  if ((outside.array() > 0.0f).any()) return outside.cwiseMax(0.0f).norm();
  return -outside.maxCoeff();
}

namespace {

// The faces of a box the camera (at the origin) sees, worked out once for all the points: the
// box's frame and the visible faces' (axis, side).
struct VisibleBoxFaces {
  explicit VisibleBoxFaces(const ShapeFit& box)
      : box(box), to_box(box.orientation.conjugate()), half(0.5f * box.dimensions) {
    const Eigen::Vector3f camera = to_box * (-box.center);
    for (int axis = 0; axis < 3; ++axis) {
      for (float side : {-1.0f, 1.0f}) {
        if (!(side * camera[axis] <= half[axis])) faces[count++] = {axis, side};  // NaN: as before
      }
    }
  }
  float distance(const Eigen::Vector3f& point) const {
    const Eigen::Vector3f local = to_box * (point - box.center);
    const Eigen::Vector3f clamped = local.cwiseMax(-half).cwiseMin(half);
    // The nearest face by its squared distance, one root: the roots are monotonic (correctly
    // rounded), so the same distance as the least of the faces' norms.
    float squared = std::numeric_limits<float>::infinity();
    for (int face = 0; face < count; ++face) {
      Eigen::Vector3f nearest = clamped;
      nearest[faces[face].axis] = faces[face].side * half[faces[face].axis];
      squared = std::min(squared, (local - nearest).squaredNorm());
    }
    const float distance = std::sqrt(squared);
    return std::isfinite(distance) ? distance : distanceToBox(box, point);
  }

  const ShapeFit& box;
  const Eigen::Quaternionf to_box;
  const Eigen::Vector3f half;
  struct Face {
    int axis;
    float side;
  } faces[6] = {};
  int count = 0;
};

}  // namespace

float distanceToVisibleBoxSurface(const ShapeFit& box, const Eigen::Vector3f& point) {
  return VisibleBoxFaces(box).distance(point);
}

void distancesToVisibleBoxSurface(const ShapeFit& box, const NormalCloud& points,
                                  std::vector<float>& distances) {
  const VisibleBoxFaces visible(box);
  distances.clear();
  distances.reserve(points.size());
  for (const auto& p : points.points) distances.push_back(visible.distance(p.getVector3fMap()));
}

}  // namespace tabletop_shapes
