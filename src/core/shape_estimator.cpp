#include "tabletop_shapes/core/shape_estimator.h"

#include "tabletop_shapes/core/cube_fit.h"
#include "tabletop_shapes/core/cylinder_fit.h"
#include "tabletop_shapes/core/normals.h"
#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/predictor.h"
#include "tabletop_shapes/core/round_lid.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>

namespace tabletop_shapes {
namespace {

Eigen::Vector3f centroidOf(const Cloud& cluster) {
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  for (const auto& p : cluster.points) sum += p.getVector3fMap();
  return cluster.empty() ? sum : Eigen::Vector3f(sum / static_cast<float>(cluster.size()));
}

ShapeFit unknown(const Cloud& cluster, const std::string& reason) {
  ShapeFit fit;
  fit.type = ShapeType::Unknown;
  fit.reason = reason;
  fit.points = static_cast<int>(cluster.size());
  fit.center = centroidOf(cluster);
  return fit;
}

// No model is left: the cluster's bounding box, a safe solid for a grasp planner, which keeps
// the reasons; Unknown only when not even that can be built.
ShapeFit fallback(const Cloud& cluster, const Plane& table, const std::string& reason) {
  ShapeFit box = boundingBox(cluster, table);
  if (!box.ok) return unknown(cluster, reason + "; bounding box: " + box.reason);
  box.reason = reason;
  return box;
}

// A round fit rests on the side-wall points only. Resting on a tenth of the cluster or less it
// describes a sliver: seen on a box at 0.5 m, a cylinder through 11 of its ~900 points fitted
// to 1.9 mm, better than the box could. Real cylinders and cones use 30-90 % of their points.
constexpr float kMinFitFraction = 0.1f;

ShapeFit checkSupport(ShapeFit fit, size_t cluster_size) {
  if (fit.ok && fit.points < kMinFitFraction * static_cast<float>(cluster_size)) {
    fit.ok = false;
    fit.reason = "the " + std::string(shapeTypeName(fit.type)) + " rests on only " +
                 std::to_string(fit.points) + " of " + std::to_string(cluster_size) + " points";
  }
  return fit;
}

// Points the model comparison is judged on: the closest 90 % to each model's surface. The rest
// may be flying pixels along the line of sight behind an edge: on a 5 cm box at 1.1 m, 5 % of
// the cluster, up to 10 cm off, which dominate any plain RMS.
constexpr float kComparedFraction = 0.9f;

// How well the fitted solid explains the points as the camera saw them, comparable between
// models: RMS distance of the closest kComparedFraction of the cluster's points to the part of
// the solid's surface that faces the camera. A point behind that surface means the camera saw
// through the solid; a point beside it, a solid too small. A plain distance to the surface
// favours flexible models: points inside a too large cone lie near its hidden back wall too.
// The fits' own rmse is not comparable either: the box's covers all the points, flying pixels
// included, the round fit's only the side-wall points it kept (cylinders through the sides of
// flat boxes at 0.7-1.25 m claimed 2.5-8.4 mm against the boxes' 4.9-14 mm, while 90 % of the
// points lay within 0.3-0.5 mm RMS of the boxes' surfaces and 1.1-14 mm of the cylinders').
float visibleSurfaceResidual(const ShapeFit& fit, const NormalCloud& cluster) {
  std::vector<float> squared;
  if (fit.type == ShapeType::Cube) {
    distancesToVisibleBoxSurface(fit, cluster, squared);
  } else {
    distancesToVisibleRoundSurface(fit, cluster, squared);
  }
  for (float& distance : squared) distance *= distance;
  if (squared.empty()) return 0.0f;
  const size_t kept = std::max<size_t>(
      1, static_cast<size_t>(kComparedFraction * static_cast<float>(squared.size())));
  std::nth_element(squared.begin(), squared.begin() + (kept - 1), squared.end());
  double sum = 0.0;
  for (size_t i = 0; i < kept; ++i) sum += squared[i];
  return static_cast<float>(std::sqrt(sum / static_cast<double>(kept)));
}

// Lowest and highest coordinate of the cluster's points along `direction`.
Eigen::Vector2f extentAlong(const Cloud& cluster, const Eigen::Vector3f& direction) {
  Eigen::Vector2f range(std::numeric_limits<float>::max(), -std::numeric_limits<float>::max());
  for (const auto& p : cluster.points) {
    const float coordinate = direction.dot(p.getVector3fMap());
    if (!std::isfinite(coordinate)) continue;
    range = {std::min(range[0], coordinate), std::max(range[1], coordinate)};
  }
  return range;
}

std::string formatMetres(float value) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(3) << value;
  return text.str();
}

// Depth cameras lose the returns of surfaces seen at grazing incidence (Kinect-class sensors
// beyond ~70-80 degrees; preprocess also drops points within flying_pixel_angle_deg of the
// line of sight), so the points of a round wall end before its silhouette: at sin(70 deg) of
// its radius across the line of sight. On real OSD scenes, cylinders fitted to cans and bowls
// 8-20 cm across were 6-14 mm wider than their points.
const float kSilhouetteFraction = std::sin(70.0f * static_cast<float>(kPi) / 180.0f);

// Where the camera's view cuts the cluster: the directions (optical frame) in which it
// continues out of view. Image borders: the points reach within two pixels and half the point
// spacing (where voxel centroids end) of the valid pixels' bounds. Near limit: they reach the
// frame's nearest valid depth (plus the point spacing), and that depth is the camera's near
// limit (nearCutDepth); the direction is then towards the camera.
// Without a known near limit: depth cameras' near limits lie within 0.6 m (Kinect v1 / Xtion
// ~0.45-0.5 m, RealSense D4xx less); a frame whose nearest point is farther is not cut by it.
// Without this bound the nearest object of every real OSD frame (walls and floor cropped) was
// flagged as cut.
constexpr float kFarthestNearLimit = 0.6f;
// With a known near limit, a surface cut by it has its nearest points within this of it: its
// voxel centroids lie up to half a voxel beyond, plus depth noise and quantisation (a Kinect's
// depth steps are ~1.5 mm at 0.5 m).
constexpr float kNearLimitMargin = 0.02f;

// The depth below which a frame's points are cut by the camera's near limit: its nearest valid
// depth, when that can be the near limit (`near_limit`, ShapeEstimatorParams; 0: unknown); else
// 0, no near cut. A frame whose nearest object stands beyond the near limit is not cut: a
// RealSense (near limit 0.28 m) marker at 0.57 m, the nearest object of its frame, was taken as
// cut under the 0.6 m bound, and its thin-object rule was turned off (r 18 mm for 9).
float nearCutDepth(const ViewBounds& view, float near_limit) {
  if (!(view.min_depth > 0.0f)) return 0.0f;
  const float farthest = near_limit > 0.0f ? near_limit + kNearLimitMargin : kFarthestNearLimit;
  return view.min_depth < farthest ? view.min_depth + view.point_spacing : 0.0f;
}

// Height slices in which trimEdgeBleed finds a cluster's sides [m]: two voxels.
constexpr float kBleedSlice = 0.01f;

int heightSlice(const Point& p, const Eigen::Vector3f& up) {
  return static_cast<int>(std::floor(up.dot(p.getVector3fMap()) / kBleedSlice));
}

// Lowest and highest coordinate along `across` of the cluster's points in each height slice
// (heightSlice), by slice.
std::map<int, Eigen::Vector2f> sliceSides(const Cloud& cluster, const Eigen::Vector3f& up,
                                          const Eigen::Vector3f& across) {
  std::map<int, Eigen::Vector2f> sides;
  for (const auto& p : cluster.points) {
    const int slice = heightSlice(p, up);
    const float x = across.dot(p.getVector3fMap());
    auto [it, inserted] = sides.emplace(slice, Eigen::Vector2f(x, x));
    if (!inserted) it->second = {std::min(it->second[0], x), std::max(it->second[1], x)};
  }
  return sides;
}

struct Cuts {
  // Where the object continues out of view across its height (its width there is cut).
  std::vector<Eigen::Vector3f> directions;
  // Borders (as directions) that cut only the object's top (cutsOnlyTheTop): its height is a
  // lower bound and its top face is cut there, its width across the line of sight is whole.
  std::vector<Eigen::Vector3f> top_only;
  bool near = false;
};

// Where the image's left or right border cuts an upright object tells what it cuts. On a steep
// view the vertical edges of an object beside the image's side lean outward, and its top leaves
// the image first: a RealSense marker 0.46 m away, 140 mm tall, reached the left border only in
// its top 3 of 15 height slices (1 cm), while below it was seen whole, 9 px from the border, and
// its width rules were off (r 11.3 mm for 9). A side border that only the upper half of the
// cluster's height reaches, in slices no wider than the widest slice below them (a bowl's rim,
// wider than its foot, is cut across), cuts only its top.
bool cutsOnlyTheTop(const Cloud& cluster, float lowest_at_border, const Eigen::Vector3f& up) {
  const Eigen::Vector2f heights = extentAlong(cluster, up);
  if (!(lowest_at_border > 0.5f * (heights[0] + heights[1]))) return false;
  const Eigen::Vector3f centroid = centroidOf(cluster);
  const Eigen::Vector3f sight = centroid - up.dot(centroid) * up;  // horizontal
  if (sight.norm() < 1e-6f) return false;
  const int first_cut_slice = static_cast<int>(std::floor(lowest_at_border / kBleedSlice));
  float widest_below = 0.0f, widest_cut = 0.0f;
  for (const auto& [slice, side] : sliceSides(cluster, up, up.cross(sight.normalized()))) {
    float& widest = slice < first_cut_slice ? widest_below : widest_cut;
    widest = std::max(widest, side[1] - side[0]);
  }
  return widest_cut <= widest_below;
}

Cuts findCuts(const Cloud& cluster, const ViewBounds* view, float near_limit,
              const Eigen::Vector3f& up) {
  Cuts cuts;
  if (!view || !view->known) return cuts;
  const float near_cut = nearCutDepth(*view, near_limit);
  // Per border (left, right, top, bottom of the image): the lowest height of a point reaching it.
  float lowest_at_border[4];
  std::fill(std::begin(lowest_at_border), std::end(lowest_at_border),
            std::numeric_limits<float>::infinity());
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  for (const auto& p : cluster.points) {
    if (!(p.z > 0.0f) || !std::isfinite(p.x) || !std::isfinite(p.y)) continue;
    const float margin = 2.0f * view->pixel_tan + 0.5f * view->point_spacing / p.z;
    const bool at_border[4] = {
        p.x / p.z<view->min_tan_x + margin, p.x / p.z> view->max_tan_x - margin,
        p.y / p.z<view->min_tan_y + margin, p.y / p.z> view->max_tan_y - margin};
    const float height = up.dot(p.getVector3fMap());
    for (int i = 0; i < 4; ++i) {
      if (at_border[i]) lowest_at_border[i] = std::min(lowest_at_border[i], height);
    }
    cuts.near |= p.z < near_cut;
    centroid += p.getVector3fMap();
  }
  const Eigen::Vector3f borders[4] = {-Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitX(),
                                      -Eigen::Vector3f::UnitY(), Eigen::Vector3f::UnitY()};
  for (int i = 0; i < 4; ++i) {
    if (!std::isfinite(lowest_at_border[i])) continue;
    const bool side_border = i < 2;
    (side_border && cutsOnlyTheTop(cluster, lowest_at_border[i], up) ? cuts.top_only
                                                                     : cuts.directions)
        .push_back(borders[i]);
  }
  if (cuts.near && centroid.norm() > 0.0f) cuts.directions.push_back(-centroid.normalized());
  return cuts;
}

// The directions in which the view cut the object's top face: across its height or at its top.
std::vector<Eigen::Vector3f> topFaceCuts(const Cuts& cuts) {
  std::vector<Eigen::Vector3f> all = cuts.directions;
  all.insert(all.end(), cuts.top_only.begin(), cuts.top_only.end());
  return all;
}

// A cut direction has a component along a direction beyond this (~17 degrees off square).
constexpr float kAlong = 0.3f;

// A round solid whose axis is nearer the table than up (fitLyingCylinder).
bool isLying(const ShapeFit& fit, const Eigen::Vector3f& up) {
  return fit.type != ShapeType::Cube && std::abs(fit.axis().dot(up)) < std::cos(kPi / 4);
}

// Empty when the solid, `seen_half_width` to each side of its centre across the line of sight
// (horizontal `across`), stays within `tolerance` of the cluster's points there, else why not.
// Both sides are the silhouette the camera saw, unless cut by the image border.
std::string widerThanPointsAcrossSight(const std::string& name, const ShapeFit& fit,
                                       const Cloud& cluster, const Eigen::Vector3f& across,
                                       float seen_half_width, float tolerance, const Cuts& cuts) {
  bool cut_side[2] = {false, false};  // along -across, +across
  for (const Eigen::Vector3f& d : cuts.directions) {
    cut_side[0] |= d.dot(across) < -kAlong;
    cut_side[1] |= d.dot(across) > kAlong;
  }
  const Eigen::Vector2f width = extentAlong(cluster, across);
  const float centre = across.dot(fit.center);
  if (!cut_side[0] && centre - seen_half_width < width[0] - tolerance) {
    return name + " footprint across the line of sight reaches " +
           formatMetres(width[0] - (centre - seen_half_width)) + " m beyond its points";
  }
  if (!cut_side[1] && centre + seen_half_width > width[1] + tolerance) {
    return name + " footprint across the line of sight reaches " +
           formatMetres(centre + seen_half_width - width[1]) + " m beyond its points";
  }
  if (!cut_side[0] && !cut_side[1] && 2.0f * seen_half_width > width[1] - width[0] + tolerance) {
    return name + " is " + formatMetres(2.0f * seen_half_width) +
           " m wide in view (as far as its round walls are seen), its points are " +
           formatMetres(width[1] - width[0]) + " m wide across the line of sight";
  }
  return "";
}

// overreach() of a lying cylinder below its top: its ends beyond its points along the axis
// (unless cut there), and its side facing the camera across the axis, as far as the wall is in
// view (kSilhouetteFraction), in front of its points (its far side is hidden). `beyond` is
// overreach()'s footprint check.
template <typename Beyond>
std::string lyingOverreach(const ShapeFit& fit, const Cloud& cluster, const Eigen::Vector3f& up,
                           float tolerance, const Cuts& cuts, const Beyond& beyond) {
  const Eigen::Vector3f axis = fit.axis();
  const auto cut_along = [&](const Eigen::Vector3f& direction) {
    return cuts.near || std::any_of(cuts.directions.begin(), cuts.directions.end(),
                                    [&](const Eigen::Vector3f& d) {
                                      return std::abs(d.dot(direction)) > kAlong;
                                    });
  };
  if (!cut_along(axis)) {
    std::string why = beyond(axis, 0.5f * fit.height, "length");
    if (!why.empty()) return why;
  }
  // Its footprint's width across the line of sight, as far as round rims are in view (its
  // ends' rims turn away from the camera too): a lying cylinder r 49 mm through a mug's handle
  // and edge smear at 1.16 m was 12 cm wide in view, its points 8.4 cm.
  const Eigen::Vector3f sight = fit.center - up.dot(fit.center) * up;  // horizontal
  if (sight.norm() > 1e-6f && !cuts.near) {
    const Eigen::Vector3f sight_across = up.cross(sight.normalized());
    const Eigen::Vector3f wall_across = up.cross(axis).normalized();  // horizontal, across the axis
    const float seen_half_width =
        kSilhouetteFraction * (0.5f * fit.height * std::abs(axis.dot(sight_across)) +
                               fit.radius * std::abs(wall_across.dot(sight_across)));
    std::string why = widerThanPointsAcrossSight("lying cylinder", fit, cluster, sight_across,
                                                 seen_half_width, tolerance, cuts);
    if (!why.empty()) return why;
  }
  Eigen::Vector3f across = fit.orientation * Eigen::Vector3f::UnitY();
  if (across.dot(-fit.center) < 0.0f) across = -across;  // towards the camera
  if (cut_along(across)) return "";
  const float near_side = across.dot(fit.center) + fit.radius * kSilhouetteFraction;
  const float nearest = extentAlong(cluster, across)[1];
  if (near_side > nearest + tolerance) {
    return "lying cylinder near side " + formatMetres(near_side - nearest) +
           " m in front of its points";
  }
  return "";
}

// Empty when the solid stays within `tolerance` of the cluster's points, else why not: its top
// above their highest point; a box's footprint beyond their extent along its edges; a round
// solid's diameter (the part in view, kSilhouetteFraction) wider than they are across the line
// of sight (camera at the origin), or its near side in front of them (its far side is hidden,
// its bottom the table).
// A cut object's points end at the cut: there the round solid may go on (a cut box's flat face
// still bounds it on the other side).
// `rim_band`: the round fit's side wall ends this far below its top (CylinderParams::top_margin).
std::string overreach(const ShapeFit& fit, const Cloud& cluster, const Plane& table,
                      float tolerance, float rim_band, const Cuts& cuts) {
  const Eigen::Vector3f up = table.normal.normalized();
  const Eigen::Vector2f heights = extentAlong(cluster, up);
  const float table_height = -table.d / table.normal.norm();
  const bool lying = isLying(fit, up);
  const float half_height = fit.type == ShapeType::Cube ? 0.5f * fit.dimensions.z()
                            : lying                     ? fit.radius
                                                        : 0.5f * fit.height;
  const float solid_top = up.dot(fit.center) - table_height + half_height;
  const float points_top = heights[1] - table_height;
  const std::string name = shapeTypeName(fit.type);
  if (solid_top > points_top + tolerance) {
    return name + " top " + formatMetres(solid_top) + " m above the table, its points reach " +
           formatMetres(points_top) + " m";
  }
  auto beyond = [&](const Eigen::Vector3f& direction, float half_width, const char* what) {
    const Eigen::Vector2f points = extentAlong(cluster, direction);
    const float centre = direction.dot(fit.center);
    if (centre - half_width >= points[0] - tolerance &&
        centre + half_width <= points[1] + tolerance) {
      return std::string();
    }
    return name + " " + what + " reaches " +
           formatMetres(
               std::max(points[0] - (centre - half_width), centre + half_width - points[1])) +
           " m beyond its points";
  };
  if (fit.type == ShapeType::Cube) {
    for (int axis = 0; axis < 2; ++axis) {
      const Eigen::Vector3f edge = fit.orientation * Eigen::Vector3f::Unit(axis);
      std::string why = beyond(edge, 0.5f * fit.dimensions[axis], axis == 0 ? "length" : "width");
      if (!why.empty()) return why;
    }
    return "";
  }
  if (lying) return lyingOverreach(fit, cluster, up, tolerance, cuts, beyond);
  const float radius =
      fit.type == ShapeType::Cone ? std::max(fit.radius_bottom, fit.radius_top) : fit.radius;
  // Its points end where the wall turns beyond 70 degrees from the camera.
  const float seen_radius = radius * kSilhouetteFraction;
  const Eigen::Vector3f sight = fit.center - up.dot(fit.center) * up;  // horizontal
  if (sight.norm() < 1e-6f) return "";  // seen from straight above: the top disc bounds it
  const Eigen::Vector3f forward = sight.normalized(), across = up.cross(forward);
  if (cuts.near) return "";  // its near side and its width are cut
  std::string why =
      widerThanPointsAcrossSight(name, fit, cluster, across, seen_radius, tolerance, cuts);
  if (!why.empty()) return why;
  // Its near side where the wall was measured: a cone's radius in the rim band above is
  // extrapolated, and a curved wall bends away from the straight taper there (on real OSD bowls
  // 17 cm across the cone reached 7-8 mm in front of the near rim).
  const float measured_top = std::max(0.0f, fit.height - rim_band) / std::max(fit.height, 1e-6f);
  const float measured_radius =
      fit.type == ShapeType::Cone
          ? std::max(fit.radius_bottom,
                     fit.radius_bottom + measured_top * (fit.radius_top - fit.radius_bottom))
          : radius;
  const float near_side = forward.dot(fit.center) - measured_radius;
  const float nearest = extentAlong(cluster, forward)[0];
  if (near_side < nearest - tolerance) {
    return name + " near side " + formatMetres(nearest - near_side) + " m in front of its points";
  }
  return "";
}

// The median over height slices of each side (sliceSides): a slice's side is its farthest
// smeared row, so the union of the slices holds the farthest smear of the whole object.
Eigen::Vector2f medianSides(const std::map<int, Eigen::Vector2f>& sides) {
  std::vector<float> low, high;
  for (const auto& [slice, side] : sides) {
    low.push_back(side[0]);
    high.push_back(side[1]);
  }
  const size_t middle = low.size() / 2;
  std::nth_element(low.begin(), low.begin() + middle, low.end());
  std::nth_element(high.begin(), high.begin() + middle, high.end());
  return {low[middle], high[middle]};
}

// What narrowToPoints knows of the camera's edge smear (ShapeEstimatorParams::edge_bleed_px).
struct EdgeSmear {
  float side = 0.0f;   // sideSmear() [m]
  float pixel = 0.0f;  // one pixel at the cluster's depth [m]; 0: no smear or no view
};

// An object narrower than this many pixels (its median width less the smear) is thin: the
// smear and blur of its sides (3.75 px each) are half its width and more. The rendered 18 mm
// markers at 0.5-1.1 m are 6-13 px wide; the next narrowest everyday objects, flat bottles 50 mm
// across, are 16 px wide at 1.2 m (with 16 px, one of them was taken for thin).
constexpr float kThinObjectPx = 14.0f;

// True when the `smeared` points are those of a thin object (kThinObjectPx), with its `sides`
// along `across`: the median over height slices of the points' sides, less `smear.side`.
bool thinObjectSides(const Cloud& smeared, const Eigen::Vector3f& up, const Eigen::Vector3f& across,
                     const EdgeSmear& smear, Eigen::Vector2f& sides) {
  if (!(smear.pixel > 0.0f) || smeared.empty()) return false;
  const Eigen::Vector2f median = medianSides(sliceSides(smeared, up, across));
  const float width = median[1] - median[0] - 2.0f * smear.side;
  if (!(width > 0.0f && width < kThinObjectPx * smear.pixel)) return false;
  sides = {median[0] + smear.side, median[1] - smear.side};
  return true;
}

// With a camera that smears edges (ShapeEstimatorParams::edge_bleed_px), a thin round object's
// depth noise (4 mm at 1 m) is as large as its radius: its circle's curvature is noise (an
// 18 mm marker's circles came out 12-46 mm across), its width across the line of sight is not.
// A cylinder wider than its points there (the width rule of overreach()) is narrowed to them:
// centred between its points across the line of sight, its near side kept, its radius half
// their width, the extent of the points left after trimEdgeBleed (`trimmed`). A thin object's
// (kThinObjectPx) radius is always half its width, measured as the median over height slices
// of the sides of the `smeared` points, less `smear.side` on each side: a slice's side is its
// farthest smeared row, and the union of the slices the farthest row of the whole object (it
// left 2-6 mm of smear on the markers' radius). A cut side or a cone is left to the rule.
ShapeFit narrowToPoints(ShapeFit fit, const Cloud& trimmed, const Cloud& smeared,
                        const EdgeSmear& smear, const Plane& table, float tolerance,
                        const Cuts& cuts) {
  if (!fit.ok || fit.type != ShapeType::Cylinder || !cuts.directions.empty()) return fit;
  const Eigen::Vector3f up = table.normal.normalized();
  if (std::abs(fit.axis().dot(up)) < 0.9f) return fit;  // a lying cylinder's width is its length
  const Eigen::Vector3f sight = fit.center - up.dot(fit.center) * up;  // horizontal
  if (sight.norm() < 1e-6f) return fit;
  const Eigen::Vector3f forward = sight.normalized(), across = up.cross(forward);
  Eigen::Vector2f sides = extentAlong(trimmed, across);
  const bool thin = thinObjectSides(smeared, up, across, smear, sides);
  const float half_width = 0.5f * (sides[1] - sides[0]);
  if (!thin && fit.radius * kSilhouetteFraction <= half_width + 0.5f * tolerance) return fit;
  const float near_side = forward.dot(fit.center) - fit.radius;
  fit.center += (0.5f * (sides[0] + sides[1]) - across.dot(fit.center)) * across +
                (near_side + half_width - forward.dot(fit.center)) * forward;
  fit.radius = half_width;
  return fit;
}

// A box's top corner farther than this from every point of its cluster is empty: the camera
// saw the table through it. A box around a can's lid leaves its corners 0.41 r off the rim
// (14-18 mm for the rendered soup and short wide cans); the rendered boxes and flat bottles
// (rounded edges) had points within 10 mm of all their top corners but one.
constexpr float kCornerGap = 0.01f;
constexpr int kMinEmptyCorners = 3;
constexpr float kRoundResidualFactor = 2.5f;

// The corners of a box's top face farther than kCornerGap from every point of the cluster.
// Corners towards a direction in which the view cut the object are not counted.
int emptyTopCorners(const ShapeFit& box, const Cloud& cluster, const Cuts& cuts) {
  if (cuts.near) return 0;
  const std::vector<Eigen::Vector3f> top_cuts = topFaceCuts(cuts);
  const Eigen::Vector3f x = box.orientation * Eigen::Vector3f::UnitX();
  const Eigen::Vector3f y = box.orientation * Eigen::Vector3f::UnitY();
  const Eigen::Vector3f z = box.orientation * Eigen::Vector3f::UnitZ();
  int empty = 0;
  for (int corner = 0; corner < 4; ++corner) {
    const Eigen::Vector3f offset = ((corner & 1) ? 0.5f : -0.5f) * box.dimensions.x() * x +
                                   ((corner & 2) ? 0.5f : -0.5f) * box.dimensions.y() * y;
    if (std::any_of(top_cuts.begin(), top_cuts.end(),
                    [&](const Eigen::Vector3f& d) { return d.dot(offset.normalized()) > kAlong; }))
      continue;
    const Eigen::Vector3f at = box.center + offset + 0.5f * box.dimensions.z() * z;
    empty += std::none_of(cluster.points.begin(), cluster.points.end(), [&](const Point& p) {
      return (p.getVector3fMap() - at).norm() <= kCornerGap;
    });
  }
  return empty;
}

// A box whose footprint's sides lie within this ratio of each other is square.
constexpr float kSquareRatio = 1.2f;

// True for a box with a square footprint (kSquareRatio) no taller than it is wide: the box
// around a short wide can, whose wall points are too few for its own round fit (a can 85 mm
// across and 33 mm high, seen over its lid: a cylinder through its wall rested on under a tenth
// of the cluster and was rejected, and the box stayed with 3-4 of its top corners empty).
bool isSquareAndLow(const ShapeFit& box) {
  const float width = std::min(box.dimensions.x(), box.dimensions.y());
  const float length = std::max(box.dimensions.x(), box.dimensions.y());
  return !box.bounding_box && width > 0.0f && length <= kSquareRatio * width &&
         box.dimensions.z() <= width;
}

// The upright cylinder inscribed in `box`: same centre, height and vertical axis, its diameter
// the footprint's shorter side.
ShapeFit inscribedCylinder(const ShapeFit& box) {
  ShapeFit cylinder = box;
  cylinder.type = ShapeType::Cylinder;
  cylinder.radius = 0.5f * std::min(box.dimensions.x(), box.dimensions.y());
  cylinder.height = box.dimensions.z();
  cylinder.dimensions = Eigen::Vector3f::Zero();
  cylinder.faces_seen = 0;
  return cylinder;
}

// A lid's points lie within its circle: a box top's beyond the circle inscribed in it, along its
// edges towards the corners left (a real OSD box, learn26, with 3 empty corners). At most this
// fraction of the points within kTopBand of the top may lie beyond the circle by more than
// max_overreach.
constexpr float kMaxOutsideLid = 0.05f;
constexpr float kTopBand = 0.01f;  // [m]

// True when the points within kTopBand of the box's top lie within the circle inscribed in its
// footprint (kMaxOutsideLid), `tolerance` beyond it allowed.
bool topIsALid(const ShapeFit& box, const Cloud& cluster, float tolerance) {
  const Eigen::Vector3f z = box.orientation * Eigen::Vector3f::UnitZ();
  const float top = z.dot(box.center) + 0.5f * box.dimensions.z();
  const float radius = 0.5f * std::min(box.dimensions.x(), box.dimensions.y());
  int on_top = 0, outside = 0;
  for (const auto& p : cluster.points) {
    const Eigen::Vector3f offset = p.getVector3fMap() - box.center;
    if (!(z.dot(p.getVector3fMap()) >= top - kTopBand)) continue;
    ++on_top;
    outside += (offset - z.dot(offset) * z).norm() > radius + tolerance;
  }
  return on_top > 0 && outside <= kMaxOutsideLid * static_cast<float>(on_top);
}

ShapeFit rejectOverreach(ShapeFit fit, const Cloud& cluster, const Plane& table, float tolerance,
                         float rim_band, const Cuts& cuts) {
  if (!fit.ok) return fit;
  const std::string why = overreach(fit, cluster, table, tolerance, rim_band, cuts);
  if (!why.empty()) {
    fit.ok = false;
    fit.reason = why + " (max_overreach " + formatMetres(tolerance) + " m)";
  }
  return fit;
}

// The points must follow the solid's visible surface (visibleSurfaceResidual) to within this
// fraction of the cluster's footprint. A solid much smaller than its points (seen on a real
// bowl: a box 14 x 13 mm in a cluster 17 cm across, 65 mm RMS off) breaks no overreach rule
// but explains nothing; right models follow their points to 0.2-1.5 mm on rendered scenes and
// to 0.5-12 mm on real OSD scenes (a mug with its handle).
constexpr float kMaxResidualFraction = 0.2f;

// `residual`, when given, receives the visibleSurfaceResidual of a fit left ok, for the model
// choice (it costs a distance to the solid per point).
ShapeFit rejectUnexplained(ShapeFit fit, const NormalCloud& normals, const Cloud& cluster,
                           const Plane& table, float* residual_out = nullptr) {
  if (!fit.ok) return fit;
  const Eigen::Vector3f up = table.normal.normalized();
  const Eigen::Vector3f e1 = up.unitOrthogonal(), e2 = up.cross(e1);
  const Eigen::Vector2f x = extentAlong(cluster, e1), y = extentAlong(cluster, e2);
  const float footprint = std::max(x[1] - x[0], y[1] - y[0]);
  const float residual = visibleSurfaceResidual(fit, normals);
  if (residual_out) *residual_out = residual;
  if (residual > kMaxResidualFraction * footprint) {
    fit.ok = false;
    fit.reason = "its points lie " + formatMetres(residual) + " m RMS off the " +
                 shapeTypeName(fit.type) + "'s visible surface, more than " +
                 formatMetres(kMaxResidualFraction * footprint) + " m (a fifth of their " +
                 formatMetres(footprint) + " m footprint)";
  }
  return fit;
}

// A round fit of a cluster cut by the image border rests on the part of its wall in view. A flat
// face seen partly is as near a circle of any large radius as a line: the visible arc must bow
// out of its chord (its sagitta) by this many times the RMS of the wall's residuals. Border boxes
// were typed round through one face (a lying cylinder r 88 mm through the 102 points of a box
// seen along the image's bottom border).
constexpr float kMinSagittaResiduals = 3.0f;
// Side-wall points lie within this many residual RMS (and at least kMinArcBand) of the wall.
constexpr float kArcBandResiduals = 3.0f;
constexpr float kMinArcBand = 0.003f;

// The arc of a round solid's wall that a cluster covers (visibleArc).
struct VisibleArc {
  float sagitta = 0.0f;  // how far it bows out of its chord [m]
  float rms = 0.0f;      // RMS distance of its points to the wall [m]
};

// The arc of the round solid's wall that `cluster` covers: the circle less its largest gap
// around the axis between side-wall points (within the band of the wall, short of the rim
// band at the top or the end facing the camera). Its sagitta is the radius times 1 - cos(half
// the arc's angle).
VisibleArc visibleArc(const ShapeFit& round, const Cloud& cluster, float rim_band) {
  const Eigen::Vector3f axis = round.axis();
  const Eigen::Vector3f e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  const float band = std::max(kArcBandResiduals * round.rmse, kMinArcBand);
  std::vector<float> angles;
  double squared = 0.0;
  for (const auto& p : cluster.points) {
    const Eigen::Vector3f offset = p.getVector3fMap() - round.center;
    const float along = axis.dot(offset);
    if (!std::isfinite(along) || along > 0.5f * round.height - rim_band) continue;
    const float fraction = std::clamp(along / round.height + 0.5f, 0.0f, 1.0f);  // 0: bottom
    const float radius =
        round.type == ShapeType::Cone
            ? round.radius_bottom + (round.radius_top - round.radius_bottom) * fraction
            : round.radius;
    const float x = e1.dot(offset), y = e2.dot(offset);
    const float off = std::hypot(x, y) - radius;
    if (std::abs(off) > band) continue;
    angles.push_back(std::atan2(y, x));
    squared += off * off;
  }
  VisibleArc arc;
  if (angles.size() < 2) return arc;
  const float gap = largestAngularGap(angles);
  arc.sagitta = round.radius * (1.0f - std::cos(0.5f * (2.0f * static_cast<float>(kPi) - gap)));
  arc.rms = static_cast<float>(std::sqrt(squared / static_cast<double>(angles.size())));
  return arc;
}

// A round fit (upright or lying) of a cluster cut by the view whose visible arc (visibleArc)
// bows out of its chord by less than kMinSagittaResiduals times its points' RMS distance to the
// wall (or the fit's own residual RMS, if larger) is rejected, with the reason. (The fit's RMS
// alone is that of the points it kept: a lying cylinder r 88 mm through the bottom 102 points
// of a Kinect border box at 0.51 m kept 98 at 0.33 mm, while the arc's points lay 1.3 mm RMS
// off its wall, its sagitta 1.8 mm.)
ShapeFit rejectFlatArc(ShapeFit fit, const Cloud& cluster, float rim_band, const Cuts& cuts) {
  if (!fit.ok || fit.type == ShapeType::Cube || cuts.directions.empty()) return fit;
  const VisibleArc arc = visibleArc(fit, cluster, rim_band);
  const float least = kMinSagittaResiduals * std::max(arc.rms, fit.rmse);
  if (arc.sagitta < least) {
    fit.ok = false;
    fit.reason = "cut by the view, its visible arc bows " + formatMetres(arc.sagitta) +
                 " m out of its chord, less than " + formatMetres(least) +
                 " m (3 x its points' RMS off the wall): a flat face seen partly";
  }
  return fit;
}

// Marks a cut solid truncated: its extents along the cut directions are lower bounds, and its
// height when the view cut only its top.
void markTruncation(const Cuts& cuts, const Eigen::Vector3f& up, ShapeFit& fit) {
  if (!cuts.top_only.empty()) {
    fit.truncated = true;
    if (fit.type == ShapeType::Cube) {
      int vertical = 0;
      (fit.orientation.conjugate() * up).cwiseAbs().maxCoeff(&vertical);
      fit.lower_bound[vertical] = true;
    } else if (isLying(fit, up)) {
      fit.lower_bound[0] = fit.lower_bound[1] = true;
    } else {
      fit.lower_bound[2] = true;
    }
  }
  for (const Eigen::Vector3f& d : cuts.directions) {
    fit.truncated = true;
    if (fit.type == ShapeType::Cube) {
      for (int axis = 0; axis < 3; ++axis) {
        fit.lower_bound[axis] |=
            std::abs(d.dot(fit.orientation * Eigen::Vector3f::Unit(axis))) > kAlong;
      }
    } else {  // radius across the axis, height (length) along it, upright or lying
      const Eigen::Vector3f axis = fit.axis();
      const bool across = (d - d.dot(axis) * axis).norm() > kAlong;
      fit.lower_bound[0] |= across;
      fit.lower_bound[1] |= across;
      fit.lower_bound[2] |= std::abs(d.dot(axis)) > kAlong;
    }
  }
}

// The cluster without the points an active-stereo camera smeared beyond its silhouette
// (ShapeEstimatorParams::edge_bleed_px): in every height slice, those within `bleed_px` pixels
// (at the cluster's depth, less half a voxel) of the slice's sides across the line of sight. The
// smear takes the near surface's depth, so those points stand beside the object, not on it. A side
// cut by the image border keeps its points (nothing was smeared there), as does a slice no wider
// than the band on both sides. The cluster itself when nothing is to be trimmed.
CloudConstPtr trimEdgeBleed(const CloudConstPtr& cluster, const Plane& table, float bleed_px,
                            const ViewBounds* view, const Cuts& cuts) {
  if (!(bleed_px > 0.0f) || !view || !view->known || cluster->empty()) return cluster;
  const Eigen::Vector3f up = table.normal.normalized();
  const Eigen::Vector3f centroid = centroidOf(*cluster);
  const Eigen::Vector3f sight = centroid - up.dot(centroid) * up;  // horizontal
  if (!(centroid.z() > 0.0f) || sight.norm() < 1e-6f) return cluster;
  const Eigen::Vector3f across = up.cross(sight.normalized());
  bool cut_side[2] = {false, false};  // along -across, +across
  for (const Eigen::Vector3f& d : cuts.directions) {
    cut_side[0] |= d.dot(across) < -kAlong;
    cut_side[1] |= d.dot(across) > kAlong;
  }
  // The voxel centroids at a side lie up to half a voxel inside the smeared samples.
  const float band =
      std::max(0.0f, bleed_px * view->pixel_tan * centroid.z() - 0.5f * view->point_spacing);
  if (!(band > 0.0f)) return cluster;
  std::map<int, Eigen::Vector2f> sides = sliceSides(*cluster, up, across);
  auto trimmed = std::make_shared<Cloud>();
  trimmed->header = cluster->header;
  for (const auto& p : cluster->points) {
    const Eigen::Vector2f& side = sides[heightSlice(p, up)];
    const float x = across.dot(p.getVector3fMap());
    if (side[1] - side[0] > 2.0f * band &&
        ((!cut_side[0] && x < side[0] + band) || (!cut_side[1] && x > side[1] - band))) {
      continue;
    }
    trimmed->push_back(p);
  }
  return trimmed->size() >= 10 ? trimmed : cluster;
}

// Beyond the smear of edge_bleed_px, the sides of a height slice lie this many more pixels
// outside the silhouette: the edge pixels' lateral noise and flying pixels at the smeared
// edge. On the RealSense renders (40 scenes, seed 2012) the median slice sides of the 18 mm
// markers at 0.53-1.08 m lay 3.0-4.3 px (3.75 on average) less half a voxel outside their
// silhouette.
constexpr float kSilhouetteBlurPx = 0.75f;

// How far the median slice sides (medianSides) of a cluster's points lie outside its
// silhouette, with edge smear: edge_bleed_px plus kSilhouetteBlurPx at the cluster's depth,
// less half a voxel (the outermost voxel centroids lie that far inside the outermost samples);
// none without edge smear or a known view.
EdgeSmear edgeSmear(const Cloud& cluster, float bleed_px, const ViewBounds* view) {
  EdgeSmear smear;
  if (!(bleed_px > 0.0f) || !view || !view->known) return smear;
  smear.pixel = view->pixel_tan * std::max(centroidOf(cluster).z(), 0.0f);
  smear.side =
      std::max((bleed_px + kSilhouetteBlurPx) * smear.pixel - 0.5f * view->point_spacing, 0.0f);
  return smear;
}

// A fitted box ends at its top face; a cap or a knob standing on that face belongs to the object
// too (a grasp planner needs its full height). Points more than kCapSigmas times the top face's
// noise (robust deviation of the points within kTopFaceBand of it) and at least kMinCapRise
// above it, inside the footprint, are such a part when at least kMinCapPoints of them face up
// (normal within kCapTopAngle): the part shows a top of its own. The box then rises to the
// kCapTopQuantile of their heights. The rendered flat bottles' 20 mm caps (18-121 such points,
// 11-70 facing up) stood 20-28 mm over the shoulder their box ended at (156 mm for 175). The
// rows of a can or box stacked on a box that the split leaves in the lower cluster (up to 23
// points 10-25 mm over its top) are side walls: none faces up.
constexpr float kTopFaceBand = 0.01f;  // [m]
constexpr float kCapSigmas = 3.0f;
constexpr float kMinCapRise = 0.01f;    // [m]
constexpr float kMinTopNoise = 0.001f;  // [m]
constexpr int kMinCapPoints = 5;
const float kCapTopAngle = degToRad(45.0f);
constexpr float kCapTopQuantile = 0.9f;

// `box` with its top raised to a cap standing on it (see above), from the points and normals
// it was fitted to; `box` itself without one.
ShapeFit raiseTopToCap(ShapeFit box, const NormalCloud& points) {
  if (!box.ok || box.type != ShapeType::Cube || box.bounding_box) return box;
  const Eigen::Matrix3f axes = box.orientation.toRotationMatrix();
  const Eigen::Vector3f up = axes.col(2), half = 0.5f * box.dimensions;
  std::vector<float> rises, on_top;  // heights over the top face, inside the footprint
  std::vector<bool> facing_up;
  for (const auto& p : points.points) {
    const Eigen::Vector3f local = axes.transpose() * (p.getVector3fMap() - box.center);
    if (!local.allFinite() || std::abs(local.x()) > half.x() || std::abs(local.y()) > half.y())
      continue;
    const float rise = local.z() - half.z();
    rises.push_back(rise);
    facing_up.push_back(up.dot(p.getNormalVector3fMap()) > std::cos(kCapTopAngle));
    if (std::abs(rise) <= kTopFaceBand) on_top.push_back(rise);
  }
  if (on_top.size() < static_cast<size_t>(kMinCapPoints)) return box;
  const float median = quantile(on_top, 0.5f);
  for (float& rise : on_top) rise = std::abs(rise - median);
  const float noise = std::max(1.4826f * quantile(on_top, 0.5f), kMinTopNoise);
  const float least = std::max(kCapSigmas * noise, kMinCapRise);
  std::vector<float> cap;
  int cap_top = 0;
  for (size_t i = 0; i < rises.size(); ++i) {
    if (!(rises[i] > least)) continue;
    cap.push_back(rises[i]);
    cap_top += facing_up[i];
  }
  if (cap_top < kMinCapPoints) return box;
  const float raise = quantile(cap, kCapTopQuantile);
  box.dimensions.z() += raise;
  box.center += 0.5f * raise * up;
  return box;
}

// `points` (optical frame) without those an active-stereo camera smeared above the object's top
// in the image: in every image column (kBleedSlice wide at the points' `depth`), those within
// `band` [m] of the column's topmost point, when the column spans more than twice that.
NormalCloud withoutSmearAboveTop(const NormalCloud& points, float band, float depth) {
  const float column_tan = kBleedSlice / depth, band_tan = band / depth;
  auto column = [&](const pcl::PointNormal& p) {
    return static_cast<int>(std::floor(p.x / p.z / column_tan));
  };
  std::map<int, Eigen::Vector2f> rows;  // topmost and lowest y / z of each column
  for (const auto& p : points.points) {
    const float y = p.y / p.z;
    auto [it, inserted] = rows.emplace(column(p), Eigen::Vector2f(y, y));
    if (!inserted) it->second = {std::min(it->second[0], y), std::max(it->second[1], y)};
  }
  NormalCloud kept;
  kept.header = points.header;
  for (const auto& p : points.points) {
    const Eigen::Vector2f& row = rows[column(p)];
    if (row[1] - row[0] > 2.0f * band_tan && p.y / p.z < row[0] + band_tan) continue;
    kept.push_back(p);
  }
  return kept;
}

// True when the image's top border cut the object (nothing was smeared above it there).
bool cutAtImageTop(const Cuts& cuts) {
  return std::any_of(cuts.directions.begin(), cuts.directions.end(),
                     [](const Eigen::Vector3f& d) { return d.y() < -kAlong; });
}

// A lying cylinder chosen for a cluster with the circle refitted (`fitChecked`) without the smear
// above its top in the image (withoutSmearAboveTop, EdgeSmear::side): an active-stereo camera
// smears the can's upper outline over the background behind it, at the can's depth, and those
// points stood 2-5 mm over the can (RealSense renders: radius 3-13 % large). After the model
// choice, so the type stays; only the chosen cylinder is refitted (trimming every cluster's top
// before the choice made a mug 41 % over and cost 2 % type right, session 14). Not where the
// image's top border cut the object (nothing was smeared there); `lying` itself when the refit
// fails. `table_up`: the table's unit normal.
template <typename FitChecked>
ShapeFit lyingWithoutTopSmear(const ShapeFit& lying, const NormalCloud& normals,
                              const EdgeSmear& smear, float depth, const Cuts& cuts,
                              const FitChecked& fitChecked, const Eigen::Vector3f& table_up) {
  if (!(smear.side > 0.0f) || !(depth > 0.0f) || cutAtImageTop(cuts)) return lying;
  ShapeFit refit = fitChecked(withoutSmearAboveTop(normals, smear.side, depth));
  if (!refit.ok) return lying;
  // Its length is the chosen one's, less the smear's part along the axis at its far end (the end
  // facing up the image; EdgeSmear::side along the image's up direction, square to the line of
  // sight): fitted without the band, the far end of a can along the line of sight lost 1 cm where
  // nothing was smeared (synthetic points); the rendered cans came out up to 8 % long.
  const Eigen::Vector3f axis = refit.axis();
  refit.center += axis.dot(lying.center - refit.center) * axis;
  refit.height = lying.height;
  const Eigen::Vector3f sight = refit.center.normalized();
  const Eigen::Vector3f image_up = (table_up - table_up.dot(sight) * sight).normalized();
  const Eigen::Vector3f far_end = axis.dot(image_up) >= 0.0f ? axis : Eigen::Vector3f(-axis);
  const bool far_end_cut =
      std::any_of(cuts.directions.begin(), cuts.directions.end(),
                  [&](const Eigen::Vector3f& d) { return d.dot(far_end) > kAlong; });
  const float inset = far_end_cut ? 0.0f : smear.side * far_end.dot(image_up);
  refit.height -= inset;
  refit.center -= 0.5f * inset * far_end;
  return refit;
}

// An upright round solid chosen for a cluster, its top lowered to that of the round solid refitted
// (`fitRound`) without the smear above the object's top in the image (withoutSmearAboveTop,
// EdgeSmear::side): an active-stereo camera smears the far rim or lid over the background behind
// it, at its depth, and on a steep view those points stand over the top (RealSense renders: mugs
// 97-100 mm for 95, the rim's smear a group of its own over the top, which topHeight follows).
// Only the height is taken from the refit, after the model choice, and only downwards; not where
// the image border cut the top. `upright` itself otherwise.
template <typename FitRound>
ShapeFit uprightWithoutTopSmear(const ShapeFit& upright, const NormalCloud& normals,
                                const EdgeSmear& smear, float depth, const Cuts& cuts,
                                const FitRound& fitRound) {
  if (!(smear.side > 0.0f) || !(depth > 0.0f) || cutAtImageTop(cuts) || !cuts.top_only.empty())
    return upright;
  const ShapeFit refit = fitRound(withoutSmearAboveTop(normals, smear.side, depth));
  if (!refit.ok || !(refit.height < upright.height)) return upright;
  ShapeFit lowered = upright;
  lowered.center -= 0.5f * (upright.height - refit.height) * upright.axis();
  lowered.height = refit.height;
  return lowered;
}

// The solid of a cluster of at least 10 points (ShapeEstimator::estimate): `cluster` without
// its edge smear (trimEdgeBleed), `smeared` with it, and the `smear`, for narrowToPoints.
ShapeFit estimateSolid(const ShapeEstimatorParams& params, const CloudConstPtr& cluster,
                       const Cloud& smeared, const EdgeSmear& smear, const Plane& table,
                       const Cuts& cuts) {
  NormalCloud normals;
  estimateNormalsMLS(cluster, params.normals, normals);
  if (normals.size() < 10) return fallback(*cluster, table, "too few points with a normal");

  auto checked = [&](const ShapeFit& model, float* residual = nullptr) {
    ShapeFit fit = checkSupport(model, normals.size());
    if (params.edge_bleed_px > 0.0f)
      fit = narrowToPoints(fit, *cluster, smeared, smear, table, params.max_overreach, cuts);
    fit = rejectOverreach(fit, *cluster, table, params.max_overreach, params.cylinder.top_margin,
                          cuts);
    fit = rejectFlatArc(fit, *cluster, params.cylinder.top_margin, cuts);
    return rejectUnexplained(fit, normals, *cluster, table, residual);
  };
  // A box's hidden ends lie as far outside its silhouette as a thin object's sides
  // (EdgeSmear::side): a box seen from straight above by a RealSense at 0.46 m, only its top
  // face in view, came out 46 mm across for 38 (fitCube).
  const SilhouetteSmear box_smear{smear.side, topFaceCuts(cuts)};

  // Both models are fitted, as no residual of the guess alone tells a wrong guess: on the
  // rendered benchmark, right models follow their clusters to 0.15-1.5 mm, wrong ones from
  // 0.8 mm, and a cylinder on the sides of a 16.7 x 5.6 x 7.9 cm box at 1.4 m had its own rmse
  // at 1.3 mm. The model that explains the points as seen better wins; the guess only orders
  // the reasons of a failure.
  // Beyond the paper, a cylinder lying on its side competes too: real cans and tins lie on the
  // table or stand on their rim (OSD learn30-43), and a box around them was all we had.
  // Residuals of the fits left ok (visibleSurfaceResidual).
  // The three fits are independent of each other: with one object on the table (no other
  // cluster to keep the second core busy) they run side by side, the two costlier first;
  // among several clusters freeWorkerThreads() is 1 and they run in turn.
  float box_residual = 0.0f, round_residual = 0.0f, lying_residual = 0.0f;
  ShapeFit box_fit, round_fit, lying;
  parallelFor(
      3,
      [&](size_t model) {
        if (model == 0) {
          box_fit = checked(fitCube(normals, table, params.cube, box_smear), &box_residual);
        } else if (model == 1) {
          lying = checked(fitLyingCylinder(normals, table, params.cylinder), &lying_residual);
        } else {
          round_fit = checked(fitRoundObject(normals, table, params.cylinder, params.cone),
                              &round_residual);
        }
      },
      freeWorkerThreads());
  // A thin object's circle is its median width (narrowToPoints), and its points keep some
  // smear beside it: the residuals cannot tell its round solid from a box around the smear
  // (the box won on 4 of 18 rendered RealSense markers), and the predictor's guess decides.
  const Eigen::Vector3f up = table.normal.normalized();
  const Eigen::Vector3f centroid = centroidOf(smeared);
  const Eigen::Vector3f sight = centroid - up.dot(centroid) * up;
  Eigen::Vector2f thin_sides;
  const bool thin = sight.norm() > 1e-6f &&
                    thinObjectSides(smeared, up, up.cross(sight.normalized()), smear, thin_sides);
  // The guess (§3.1) comes first: it is the thin object's model, wins an exact tie of the box's
  // and the round residual (or one that is not a number), and gives the first reason of a
  // failure. Elsewhere the residuals alone choose, so its k-nearest search over the cluster is
  // made only where it decides (it cost half the box fit's instructions).
  const bool guess_decides = (thin && (box_fit.ok || round_fit.ok)) ||
                             (!box_fit.ok && !round_fit.ok && !lying.ok) ||
                             (box_fit.ok && round_fit.ok && !(box_residual < round_residual) &&
                              !(round_residual < box_residual));
  const bool box_first =
      guess_decides && predictShape(normals, params.predictor).guess == ShapeType::Cube;
  const ShapeFit& guessed = box_first ? box_fit : round_fit;
  const ShapeFit& other = box_first ? round_fit : box_fit;
  if (thin && guessed.ok) return raiseTopToCap(guessed, normals);
  const ShapeFit* best = nullptr;
  float best_residual = std::numeric_limits<float>::infinity();
  const ShapeFit* const in_order[] = {&guessed, &other, &lying};
  for (const ShapeFit* fit : in_order) {
    if (!fit->ok) continue;
    const float residual = fit == &box_fit     ? box_residual
                           : fit == &round_fit ? round_residual
                                               : lying_residual;
    if (!best || residual < best_residual) {
      best = fit;
      best_residual = residual;
    }
  }
  // The box may explain a can's points better than its cylinder: a few wall points under a
  // large lid give a circle 2-3 mm small (r 39.9 mm for a short wide can's 42.5, 30.9 for a
  // soup can's 33), while the box around the smeared lid fits it (RealSense 0.55-1.07 m: box
  // 0.7-1.4 mm RMS, cylinder 1.0-1.6). The free space the box would fill tells them apart: at
  // least kMinEmptyCorners of its top corners empty, and the upright round solid explains the
  // points within kRoundResidualFactor of the box, standing inside its footprint as a lid in
  // its square, make the round solid the object. (Boxes had at most one empty corner and round
  // residuals 2.2-17 times theirs; a lying can's box has empty top corners too, but the
  // upright cylinder through it, r 50 mm in a box 73 mm wide, does not stand inside it.)
  if (best && best->type == ShapeType::Cube) {
    const ShapeFit& round = round_fit;
    const float round_radius = std::max({round.radius, round.radius_bottom, round.radius_top});
    if (round.ok && round.type != ShapeType::Cube && !isLying(round, up) &&
        2.0f * round_radius <=
            std::min(best->dimensions.x(), best->dimensions.y()) + params.max_overreach &&
        round_residual < kRoundResidualFactor * best_residual &&
        emptyTopCorners(*best, *cluster, cuts) >= kMinEmptyCorners) {
      return round;
    }
    if (isSquareAndLow(*best) && emptyTopCorners(*best, *cluster, cuts) >= kMinEmptyCorners &&
        topIsALid(*best, *cluster, params.max_overreach + smear.side)) {
      return inscribedCylinder(*best);
    }
  }
  // A can in a crowd shows its lid, while its neighbours hide most of its wall: too few wall
  // points for the round fit (or its width wrongly checked against the part its neighbours
  // left in view), and the box around the lid won (touching clutter: 19 of 41 cans). A round
  // outline of the box's top makes it the cylinder under that lid (round_lid.h), when that
  // cylinder explains the points about as well as the box (as the round fit must above).
  // A taller neighbour in front may hide the near part of the lid too: the outline then follows
  // the cut, and the circle is the one that holds the whole outline, judged on the far rim that
  // nothing in front can hide (isPartlyHiddenLid; touching clutter: 4 of the 8 cans still typed
  // cube, covered 2 of 9).
  // The cylinder under a round lid of `box` (ok false without one), explaining the points within
  // kRoundResidualFactor of the box's `box_residual`.
  auto cylinderUnderARoundLid = [&](const ShapeFit& box, float box_residual) {
    ShapeFit lid;
    if (!cuts.directions.empty() || !cuts.top_only.empty()) return lid;
    const float radius_min = params.cylinder.min_radius, radius_max = params.cylinder.max_radius;
    const float tolerance = params.max_overreach + smear.side;
    auto lidExplainsThePoints = [&](const TopOutline& outline) {
      lid = cylinderUnderLid(box, outline);
      return visibleSurfaceResidual(lid, normals) < kRoundResidualFactor * box_residual;
    };
    const TopOutline outline = topOutline(box, *cluster, radius_min, radius_max, tolerance);
    if (isRoundLid(outline) && lidExplainsThePoints(outline)) return lid;
    const TopOutline hidden = hiddenLidOutline(box, *cluster, radius_min, radius_max, tolerance);
    if (isPartlyHiddenLid(hidden) && lidExplainsThePoints(hidden)) return lid;
    lid.ok = false;
    return lid;
  };
  if (best && best->type == ShapeType::Cube) {
    const ShapeFit lid = cylinderUnderARoundLid(*best, best_residual);
    if (lid.ok) return lid;
  }
  if (best == &lying) {
    return lyingWithoutTopSmear(
        lying, normals, smear, centroid.z(), cuts,
        [&](const NormalCloud& points) {
          return checked(fitLyingCylinder(points, table, params.cylinder));
        },
        up);
  }
  // The models were compared at the box's fitted top; a cap raises it after the choice.
  if (best && best->type != ShapeType::Cube) {
    return uprightWithoutTopSmear(
        *best, normals, smear, centroid.z(), cuts, [&](const NormalCloud& points) {
          return fitRoundObject(points, table, params.cylinder, params.cone);
        });
  }
  if (best) return raiseTopToCap(*best, normals);

  std::ostringstream reason;
  reason << "no model fits: " << shapeTypeName(box_first ? ShapeType::Cube : ShapeType::Cylinder)
         << ": " << guessed.reason << "; "
         << shapeTypeName(box_first ? ShapeType::Cylinder : ShapeType::Cube) << ": " << other.reason
         << "; lying cylinder: " << lying.reason;
  // A round lid on the bounding box makes it the cylinder under that lid, as on a fitted box: a
  // rendered can in a crowd whose box fit found degenerate extents and whose round fit rested on
  // 40 of its 489 points, a real OSD one (learn34) whose box and cone each broke a rule.
  const ShapeFit box = fallback(*cluster, table, reason.str());
  if (box.ok && box.bounding_box) {
    const ShapeFit lid = cylinderUnderARoundLid(box, visibleSurfaceResidual(box, normals));
    if (lid.ok) return lid;
  }
  return box;
}

}  // namespace

ShapeFit ShapeEstimator::estimate(const CloudConstPtr& cluster, const Plane& table,
                                  const ViewBounds* view) const {
  if (!cluster || cluster->size() < 10) {
    return cluster ? fallback(*cluster, table, "too few points to fit a model")
                   : unknown(Cloud(), "no cluster");
  }
  const Cuts cuts = findCuts(*cluster, view, params_.near_limit, table.normal.normalized());
  ShapeFit fit =
      estimateSolid(params_, trimEdgeBleed(cluster, table, params_.edge_bleed_px, view, cuts),
                    *cluster, edgeSmear(*cluster, params_.edge_bleed_px, view), table, cuts);
  markTruncation(cuts, table.normal.normalized(), fit);
  return fit;
}

std::vector<ShapeFit> ShapeEstimator::estimateAll(const std::vector<CloudPtr>& clusters,
                                                  const std::vector<Plane>& supports,
                                                  const ViewBounds* view) const {
  std::vector<ShapeFit> fits(clusters.size());
  parallelFor(clusters.size(),
              [&](size_t i) { fits[i] = estimate(clusters[i], supports.at(i), view); });
  return fits;
}

}  // namespace tabletop_shapes
