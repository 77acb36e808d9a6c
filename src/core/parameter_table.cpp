#include "tabletop_shapes/core/parameter_table.h"

#include <cmath>
#include <sstream>

namespace tabletop_shapes {
namespace {

using Visitor = std::function<void(const ParameterInfo&, double&)>;

template <typename Field>
void visitField(const ParameterInfo& info, Field& field, const Visitor& visit) {
  double value = static_cast<double>(field);
  visit(info, value);
  field = static_cast<Field>(value);
}

}  // namespace

void forEachParameter(PipelineParams& p, const Visitor& visit) {
  auto real = [&](const char* stage, const char* name, float& field, double min, double max,
                  const char* description) {
    visitField(ParameterInfo{stage, name, min, max, false, description}, field, visit);
  };
  auto integer = [&](const char* stage, const char* name, int& field, double min, double max,
                     const char* description) {
    visitField(ParameterInfo{stage, name, min, max, true, description}, field, visit);
  };
  auto& pre = p.preprocess;
  real("preprocess", "leaf_size", pre.leaf_size, 0.0, 0.1,
       "voxel grid leaf size [m]; 0 disables the grid (§2.1)");
  real("preprocess", "max_range", pre.max_range, 0.1, 20.0,
       "points farther than this from the camera are dropped [m] (§2.1)");
  real("preprocess", "flying_pixel_angle_deg", pre.flying_pixel_angle_deg, 0.0, 45.0,
       "organised input: points whose image neighbours all lie within this angle of the line of "
       "sight are flying pixels and dropped [deg]; 0 disables");

  auto& table = p.table;
  real("table", "up_tolerance_deg", table.up_tolerance_deg, 1.0, 60.0,
       "the table normal lies within this angle of up [deg] (§2.2)");
  real("table", "distance_threshold", table.distance_threshold, 0.001, 0.1,
       "RANSAC inlier distance of the table plane [m] (§2.2)");
  integer("table", "max_iterations", table.max_iterations, 10, 100000,
          "RANSAC iterations per plane candidate (§2.2)");
  integer("table", "min_inliers", table.min_inliers, 3, 10000000,
          "a support plane needs at least this many points (§2.2)");
  integer("table", "max_planes", table.max_planes, 1, 10,
          "horizontal planes examined to find the one the objects stand on");
  real("table", "hull_margin", table.hull_margin, 0.0, 1.0,
       "objects must reach this far inside the table's convex hull [m] (§2.3)");
  real("table", "min_height", table.min_height, 0.0, 0.2,
       "object points start this far above the table [m]");
  real("table", "max_height", table.max_height, 0.01, 3.0,
       "object points end this far above the table [m]");
  real("table", "camera_height", table.camera_height, 0.0, 5.0,
       "the camera's height above the table top along up, when known [m]: the support plane is "
       "the plane at that height; 0: unknown, the highest plane with objects on it");
  real("table", "camera_height_tolerance", table.camera_height_tolerance, 0.005, 0.5,
       "how far the support plane may lie from camera_height [m]");
  integer("table", "outlier_k", table.outlier_k, 0, 500,
          "statistical outlier removal: neighbours; 0 disables it (§2.4)");
  real("table", "outlier_alpha", table.outlier_alpha, -5.0, 20.0,
       "statistical outlier removal: keep mean distance < mu + alpha * sigma (§2.4)");

  auto& cluster = p.clustering;
  real("clustering", "tolerance", cluster.tolerance, 0.001, 0.5,
       "Euclidean clustering distance d_th [m] (§2.5)");
  integer("clustering", "min_size", cluster.min_size, 1, 10000000,
          "clusters with fewer points are ignored (§2.5)");
  integer("clustering", "max_size", cluster.max_size, 1, 10000000,
          "clusters with more points are ignored");
  real("clustering", "split_concavity_deg", cluster.split_concavity_deg, 0.0, 90.0,
       "clusters split at concave seams sharper than this (stacked objects) [deg]; 0 disables");
  real("clustering", "split_patch_size", cluster.split_patch_size, 0.005, 0.2,
       "surface patch spacing of the concave-seam split [m]");
  integer("clustering", "split_min_points", cluster.split_min_points, 1, 10000000,
          "split parts with fewer points rejoin their neighbour");
  real("clustering", "split_depth_step", cluster.split_depth_step, 0.0, 0.05,
       "camera depth step at 1 m range, grows with range^2; the split's voxels follow it [m]");

  auto& shapes = p.shapes;
  real("normals", "search_radius", shapes.normals.search_radius, 0.002, 0.2,
       "moving least squares neighbourhood radius [m] (§3)");
  integer("normals", "polynomial_order", shapes.normals.polynomial_order, 0, 4,
          "moving least squares polynomial order (§3)");
  integer("predictor", "k", shapes.predictor.k, 1, 100,
          "neighbours whose normals are compared, eq. 1 (§3.1)");
  real("predictor", "threshold", shapes.predictor.threshold, 0.0, 4.0,
       "normal variation above this predicts a cylinder, else a cube (§3.1)");
  real("predictor", "section_low", shapes.predictor.section_low, 0.0, 1.0,
       "start of the representative section of the sorted variations (§3.1)");
  real("predictor", "section_high", shapes.predictor.section_high, 0.0, 1.0,
       "end of the representative section of the sorted variations (§3.1)");
  real("cube", "distance_threshold", shapes.cube.distance_threshold, 0.0005, 0.05,
       "box face inlier distance [m] (§3.2)");
  real("cube", "angle_threshold", shapes.cube.angle_threshold, 0.01, 1.57,
       "point normal vs face normal, inlier angle [rad] (§3.2)");
  real("cube", "min_support_fraction", shapes.cube.min_support_fraction, 0.0, 1.0,
       "a face needs this fraction of the object's points (§3.2)");
  real("cube", "min_plane_angle", shapes.cube.min_plane_angle, 0.01, 1.57,
       "faces closer than this angle to a kept face are rejected [rad] (§3.2)");
  integer("cube", "max_planes", shapes.cube.max_planes, 1, 3, "faces kept (§3.2)");
  integer("cube", "ransac_iterations", shapes.cube.ransac_iterations, 1, 100000,
          "RANSAC iterations for box faces (§3.2)");
  integer("cylinder", "max_refine_iterations", shapes.cylinder.max_refine_iterations, 0, 1000,
          "geometric circle refinement iterations (§3.3)");
  real("cylinder", "min_radius", shapes.cylinder.min_radius, 0.0, 1.0,
       "smaller fitted radii are rejected [m]");
  real("cylinder", "max_radius", shapes.cylinder.max_radius, 0.001, 5.0,
       "larger fitted radii are rejected [m]");
  real("cone", "min_slope", shapes.cone.min_slope, 0.0, 2.0,
       "|dr/dh| below this is a cylinder, not a truncated cone");
  real("cone", "slope_sigma", shapes.cone.slope_sigma, 0.0, 100.0,
       "the slope must exceed this many standard errors to call a cone");
  real("shapes", "max_overreach", shapes.max_overreach, 0.0, 0.1,
       "a fitted solid may reach this far beyond its points (top, footprint, round diameter "
       "across the line of sight) or it is rejected [m]");
  real("shapes", "edge_bleed_px", shapes.edge_bleed_px, 0.0, 20.0,
       "the camera smears a near surface's depth this many pixels beyond its silhouette "
       "(RealSense D4xx: 3, Kinect: 0); that band of a cluster's sides is left out of the fit");
  real("shapes", "near_limit", shapes.near_limit, 0.0, 2.0,
       "the camera's nearest measured depth [m] (Kinect: 0.45, RealSense D435: 0.28; 0: "
       "unknown, taken within 0.6 m); an object reaching it is cut (truncated)");
}

bool setParameter(PipelineParams& params, const std::string& stage, const std::string& name,
                  double value, std::string& error) {
  bool found = false;
  forEachParameter(params, [&](const ParameterInfo& info, double& field) {
    if (found || stage != info.stage || name != info.name) return;
    found = true;
    std::ostringstream why;
    if (!std::isfinite(value) || value < info.min || value > info.max) {
      why << stage << "." << name << " = " << value << " is outside [" << info.min << ", "
          << info.max << "]";
    } else if (info.is_integer && value != std::floor(value)) {
      why << stage << "." << name << " = " << value << " must be a whole number";
    } else {
      field = value;
      return;
    }
    error = why.str();
  });
  if (!found) error = "unknown parameter " + stage + "." + name;
  return found && error.empty();
}

bool validateParams(const PipelineParams& params, std::string& error) {
  std::ostringstream why;
  auto ordered = [&](const char* low_name, double low, const char* high_name, double high,
                     bool equal_allowed) {
    if (low < high || (equal_allowed && low == high)) return;
    why << (why.tellp() > 0 ? "; " : "") << low_name << " = " << low << " must be "
        << (equal_allowed ? "at most " : "below ") << high_name << " = " << high;
  };
  ordered("predictor.section_low", params.shapes.predictor.section_low, "predictor.section_high",
          params.shapes.predictor.section_high, false);
  ordered("cylinder.min_radius", params.shapes.cylinder.min_radius, "cylinder.max_radius",
          params.shapes.cylinder.max_radius, false);
  ordered("clustering.min_size", params.clustering.min_size, "clustering.max_size",
          params.clustering.max_size, true);
  ordered("table.min_height", params.table.min_height, "table.max_height", params.table.max_height,
          false);
  if (params.table.camera_height > 0) {  // 0: unknown
    ordered("table.camera_height_tolerance", params.table.camera_height_tolerance,
            "table.camera_height", params.table.camera_height, false);
  }
  error = why.str();
  return error.empty();
}

}  // namespace tabletop_shapes
