// Shared value types and per-stage parameter structs of the ROS-free core.
// Kept light: no PCL algorithm headers here, only the cloud container.
#pragma once

#include <Eigen/Geometry>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace tabletop_shapes {

// The core works on XYZ after preprocessing; colour is not used by any paper step.
using Point = pcl::PointXYZ;
using Cloud = pcl::PointCloud<Point>;
using CloudPtr = Cloud::Ptr;
using CloudConstPtr = Cloud::ConstPtr;

constexpr double kPi = 3.14159265358979323846;
inline float degToRad(float deg) { return deg * static_cast<float>(kPi) / 180.0f; }

// Plane n.p + d = 0 with |n| = 1. For the table, n points "up" (towards the camera side).
struct Plane {
  Eigen::Vector3f normal{0.0f, 0.0f, 1.0f};
  float d = 0.0f;
  float signedDistance(const Eigen::Vector3f& p) const { return normal.dot(p) + d; }
  Eigen::Vector4f coefficients() const { return {normal.x(), normal.y(), normal.z(), d}; }
};

// ---- stage parameters: SPEC.md defaults, one struct per stage ----

// §2.1
struct PreprocessParams {
  float leaf_size = 0.005f;  // voxel edge [m]; <= 0 disables the voxel grid
  float max_range = 3.0f;    // keep points with |p| <= max_range [m]
  // Organised input: a point whose image neighbours all lie within this angle of its line of
  // sight is a flying pixel (a mix of foreground and background depth at an edge) and dropped;
  // such points bridged objects standing one behind the other into one cluster [deg]. 0: off.
  float flying_pixel_angle_deg = 10.0f;
};

// §2.2-2.4
struct TableParams {
  Eigen::Vector3f up{0.0f, -1.0f, 0.0f};  // world up in the cloud frame (level optical frame)
  float up_tolerance_deg = 10.0f;         // plane normal within this angle of up
  float distance_threshold = 0.015f;      // RANSAC inlier distance [m]
  int max_iterations = 500;               // RANSAC iterations per plane
  int min_inliers = 500;                  // a support plane needs at least this many points
  int max_planes = 4;                     // horizontal planes examined (table, floor, shelves)
  // Objects must reach this far inside the table's hull [m]; their points nearer its edge are
  // kept with them, other points there (table-edge noise) are not. The paper uses 0.10 m; on
  // real OSD scenes that removed 32-100 % of the objects standing near an edge, and half of
  // PCL's mug (radius 0.054 m fitted instead of 0.039 m); 0.02 m keeps them, and the outlier
  // removal and minimum cluster size still drop table-edge noise.
  float hull_margin = 0.02f;
  float min_height = 0.008f;  // object points start this far above the plane [m]
  float max_height = 0.5f;    // and end this far above it [m]
  // The camera's height above the table top along up, when the robot knows it (tf, its own
  // build) [m]; 0: unknown. Given, the support plane is the plane found at that height (within
  // camera_height_tolerance), not the highest one with objects: on a crowded table a box top is
  // level too, and may hold more points than the table seen only in the gaps.
  float camera_height = 0.0f;
  float camera_height_tolerance = 0.05f;  // [m]
  int outlier_k = 50;                     // §2.4 neighbours
  float outlier_alpha = 3.0f;             // §2.4 keep mean-distance < mu + alpha*sigma (OSD-tuned)
};

// §2.5
struct ClusteringParams {
  float tolerance = 0.02f;  // d_th [m]
  int min_size = 100;
  int max_size = 200000;
  // Splitting clusters at concave seams (touching / stacked objects); 0 disables it.
  float split_concavity_deg = 10.0f;  // concave seams flatter than this do not split [deg]
  float split_patch_size = 0.025f;    // surface patch (supervoxel seed) spacing [m]
  int split_min_points = 150;         // smaller parts rejoin their neighbour
  // Depth step of the camera at 1 m range [m], growing with range^2 (Kinect v1 / Xtion: 1/8
  // pixel disparity = 2.9 mm); the split's voxels grow with it so that the steps do not cut
  // far surfaces apart. 0: fixed voxels.
  float split_depth_step = 0.0029f;
};

// §3: normals by moving least squares
struct NormalParams {
  float search_radius = 0.02f;  // [m]
  int polynomial_order = 2;
};

// §3.1
struct PredictorParams {
  int k = 3;  // neighbours in eq. 1
  // Above -> cylinder, else cube. The paper's 0.07 fails with MLS normals of noisy points at
  // 5 mm spacing (boxes score up to 0.11 at sigma 1 mm, cylinders r <= 6 cm from 0.14).
  float threshold = 0.13f;
  float section_low = 0.25f;  // representative middle section of the sorted d(p)
  float section_high = 0.75f;
};

// §3.2
struct CubeParams {
  float distance_threshold = 0.007f;                    // plane inlier distance [m]
  float angle_threshold = static_cast<float>(kPi / 5);  // point normal vs plane normal
  float min_support_fraction = 0.10f;                   // plane needs >= 10 % of the points
  float min_plane_angle = static_cast<float>(kPi / 6);  // reject planes closer than this
  int max_planes = 3;
  int ransac_iterations = 300;
};

// §3.3 and the truncated cone (beyond the paper)
struct CylinderParams {
  int max_refine_iterations = 50;  // geometric (Gauss-Newton) circle refinement
  float min_radius = 0.005f;       // [m]
  float max_radius = 0.3f;         // [m]
  float top_margin = 0.01f;        // side-wall points end this far below the top [m] (rim
                                   // blended into the top disc by smoothing)
};

struct ConeParams {
  float min_slope = 0.02f;   // |dr/dh| below this is a cylinder
  float slope_sigma = 3.0f;  // slope must exceed this many standard errors
};

// What the camera saw of a frame: the bounds of its valid pixels' rays. An object whose points
// reach a bound is cut by the image border, and its extents there are lower bounds. Filled from
// an organised cloud by viewBoundsOf; unknown for unorganised input.
struct ViewBounds {
  bool known = false;
  // Tangents of the valid pixels' rays, x / z and y / z in the optical frame (x right, y down).
  float min_tan_x = 0.0f, max_tan_x = 0.0f, min_tan_y = 0.0f, max_tan_y = 0.0f;
  float pixel_tan = 0.0f;  // one pixel in tangent units (1 / focal length in pixels)
  // Nearest valid depth z of the frame [m]; an object reaching it is taken as cut by the
  // sensor's near limit (0: unknown).
  float min_depth = 0.0f;
  // Spacing of the points the clusters hold (the voxel leaf) [m]: a voxel centroid at the
  // border lies up to half of it inside.
  float point_spacing = 0.0f;
};
// The bounds of an organised cloud's valid (finite, z > 0) points; unknown when the cloud is
// not organised (height 1) or has no valid point.
ViewBounds viewBoundsOf(const pcl::PointCloud<pcl::PointXYZ>& cloud);
ViewBounds viewBoundsOf(const pcl::PointCloud<pcl::PointXYZRGB>& cloud);

// ---- results ----

enum class ShapeType { Cube, Cylinder, Cone, Unknown };
const char* shapeTypeName(ShapeType type);

// One fitted object. Frame: the cloud's. `center` is the centre of the solid.
struct ShapeFit {
  ShapeType type = ShapeType::Unknown;
  bool ok = false;
  std::string reason;  // why the fit failed (ok == false)
  Eigen::Vector3f center = Eigen::Vector3f::Zero();
  // Cube: box axes (x, y, z edges = dimensions). Cylinder / cone: z = axis, pointing up.
  Eigen::Quaternionf orientation = Eigen::Quaternionf::Identity();
  Eigen::Vector3f dimensions = Eigen::Vector3f::Zero();  // cube edges [m]
  float radius = 0.0f;                                   // cylinder [m]
  float radius_bottom = 0.0f;                            // cone, at the table [m]
  float radius_top = 0.0f;                               // cone [m]
  float height = 0.0f;                                   // cylinder / cone [m]
  int points = 0;                                        // points used by the fit
  float rmse = 0.0f;                                     // fit residual RMS [m]
  int faces_seen = 0;                                    // cube only: 1-3 (0: bounding box)
  // Cube only: no model fitted (or each broke a rule), so this is the minimum-volume upright
  // box around the cluster's points, a safe solid for a grasp planner; `reason` keeps why
  // every model was rejected.
  bool bounding_box = false;
  // The object is cut by the image border: the extents flagged in `lower_bound` continue
  // beyond what the camera saw. Cube: x, y, z edges; cylinder / cone: [0] = [1] = the radius
  // (radii), [2] = the height.
  bool truncated = false;
  bool lower_bound[3] = {false, false, false};
  Eigen::Vector3f axis() const { return orientation * Eigen::Vector3f::UnitZ(); }
};

}  // namespace tabletop_shapes
