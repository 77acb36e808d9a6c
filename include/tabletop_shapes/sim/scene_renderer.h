// Rendered Kinect-v1-like or RealSense-D4xx-like test scenes: objects (boxes, cylinders,
// truncated cones, and everyday objects: bottles, bowls, mugs, lying cans) on a table, ray-cast
// into an organised 640x480 pcl::PointXYZRGB cloud in the camera OPTICAL frame (x right, y down, z
// forward; NaN = no return), with exact ground truth in the same frame. ROS-free (PCL container +
// Eigen + std). Used by tests, the accuracy benchmark and recordings.
//
// World frame: z up, floor at z = 0, table top centred above the origin, its long edge along x.
// Camera: level (no roll), looking at the objects' centre on the table top from `distance`,
// `tilt_deg` below level, `yaw_deg` the heading of the viewing direction about world z
// (yaw 0: looking along +x). Its height follows from distance and tilt.
//
// Sensor model (NoiseModel; every effect has a switch and a strength; NoiseModel::noiseless()
// turns everything off, so that each valid point lies exactly on a scene surface). Effects are
// applied to the depth image z(u, v) in this order, then every pixel is back-projected through
// its own pixel centre (x = (u - cx) z / fx), so a depth error moves the point along its ray:
//  1. lateral noise: the ray of each pixel at a surface change (a neighbour in its 3x3 sees
//     another surface or a depth jump > flying_min_jump) passes through a point jittered around
//     the pixel centre by N(0, lateral_sigma_px) in u and v, so depth edges are ragged by a
//     fraction of a pixel as with the structured-light correlation window (on a smooth surface
//     the jitter would only add sub-millimetre depth error, so it is skipped there);
//  2. flying pixels: a pixel whose clean depth differs from a 4-neighbour's by more than
//     flying_min_jump becomes, with probability flying_pixel_fraction, a point at a depth
//     drawn uniformly between the foreground and the background depth;
//  3. axial noise along the ray, Gaussian with sigma(z) = axial_sigma_base +
//     axial_sigma_quadratic * (z - axial_reference_range)^2 (Nguyen, Izadi, Lovell 2012:
//     1.2 mm + 1.9 mm * (z - 0.4 m)^2 for surfaces within ~60 deg of facing the camera);
//  4. disparity quantisation: disparity d = fx * baseline / z is rounded to multiples of
//     disparity_step_px (1/8 px on the Kinect, baseline 0.075 m), z = fx * baseline / d, which
//     gives depth steps of z^2 * step / (fx * baseline): 2.9 mm at 1 m, 11.6 mm at 2 m;
//  5. missing returns: at grazing incidence (angle between the ray and the surface normal above
//     max_incidence_deg) and random dropout with probability dropout_probability per pixel;
//  6. range limits: no return outside [min_range, max_range] (Kinect v1: ~0.45 .. ~5 m).
// Active stereo (RealSense D4xx; all off for the Kinect v1) adds, between steps 1 and 2:
//  1a. edge bleeding: the correlation window smears foreground depth over the background: a
//     pixel within edge_bleed_px (Chebyshev) of a pixel nearer by more than flying_min_jump
//     takes that pixel's depth and label, with probability 1 - (k - 1) / edge_bleed_px at
//     distance k (so ~edge_bleed_px / 2 px on average);
//  1b. stereo shadow: the depth is computed in the left imager; background the right imager
//     (baseline to the right) cannot see, because a nearer surface hides it, has no return:
//     pixel u is hidden when a pixel u' > u on its row has disparity d(u') - d(u) >= u' - u,
//     a band of fx * baseline * (1 / z_back - 1 / z_front) px left of each near edge;
// and, after step 3:
//  3a. speckle: depth noise correlated over speckle_size_px (a box-filtered unit Gaussian
//     field), sigma speckle_sigma_quadratic * z^2, as the projected pattern's speckle and the
//     correlation window give; with the per-pixel axial noise (sigma axial_sigma_quadratic *
//     z^2) the total is depthSigma(z) = z^2 * subpixel / (fx * baseline) (Intel's RMS formula,
//     0.08 px subpixel: 4.2 mm at 1 m, 17 mm at 2 m for fx 385 px, baseline 50 mm).
// Random numbers: one std::mt19937 seeded with SceneSpec::seed, drawn in a fixed order, so the
// same spec always renders the same cloud.
#pragma once

#include "tabletop_shapes/core/types.h"

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace tabletop_shapes {
namespace sim {

// The depth sensors the renderer imitates; the Kinect v1 is the default everywhere.
enum class SensorModel { KinectV1, RealSenseD435 };
const char* sensorName(SensorModel sensor);  // "kinect", "realsense"
// "kinect" / "realsense" (also "kinect-v1", "d435"); false when unknown.
bool parseSensorName(const std::string& text, SensorModel& sensor);

// Kinect v1 depth camera, VGA. Principal point at the image centre.
struct CameraIntrinsics {
  int width = 640;
  int height = 480;
  float fx = 575.8f;
  float fy = 575.8f;
  float cx = 319.5f;
  float cy = 239.5f;
  // RealSense D435 depth at 640 x 480: ~87 x 58 deg field of view.
  static CameraIntrinsics realSenseD435() { return {640, 480, 385.0f, 385.0f, 319.5f, 239.5f}; }
};

// See the file comment for the meaning and the order of the effects.
struct NoiseModel {
  bool enabled = true;  // master switch; false = noiseless (range limits still apply)

  bool lateral_noise = true;
  float lateral_sigma_px = 0.3f;  // ray jitter around the pixel centre [px]

  bool flying_pixels = true;
  float flying_pixel_fraction = 0.3f;  // of the pixels at a depth discontinuity
  float flying_min_jump = 0.03f;       // depth difference that makes a discontinuity [m]

  bool axial_noise = true;
  float axial_sigma_base = 0.0012f;       // [m]
  float axial_sigma_quadratic = 0.0019f;  // [m / m^2]
  float axial_reference_range = 0.4f;     // [m]

  bool disparity_quantisation = true;
  float baseline = 0.075f;           // projector - IR camera [m]
  float disparity_step_px = 0.125f;  // sub-pixel disparity resolution [px]

  bool grazing_dropout = true;
  float max_incidence_deg = 80.0f;  // ray vs surface normal; beyond: no return

  bool random_dropout = true;
  float dropout_probability = 0.015f;

  float min_range = 0.45f;  // depth z limits [m], applied even when noiseless
  float max_range = 5.0f;

  // Active stereo only (off for the Kinect v1; see the file comment).
  bool edge_bleeding = false;
  int edge_bleed_px = 3;  // widest smear [px]
  bool stereo_shadow = false;
  bool speckle = false;
  float speckle_sigma_quadratic = 0.0f;  // [m / m^2]
  int speckle_size_px = 5;               // correlation window edge [px]

  // Axial standard deviation at depth z [m] (the per-pixel part).
  float axialSigma(float z) const {
    const float dz = z - axial_reference_range;
    return axial_sigma_base + axial_sigma_quadratic * dz * dz;
  }
  // Standard deviation of a flat surface's depth at z, per-pixel and speckle together [m].
  float depthSigma(float z) const {
    const float axial = axial_noise ? axialSigma(z) : 0.0f;
    const float correlated = speckle ? speckle_sigma_quadratic * z * z : 0.0f;
    return std::sqrt(axial * axial + correlated * correlated);
  }
  static NoiseModel noiseless() {
    NoiseModel model;
    model.enabled = false;
    return model;
  }
  static NoiseModel kinectV1() { return {}; }
  // RealSense D435 (active stereo, baseline 50 mm) with CameraIntrinsics::realSenseD435().
  static NoiseModel realSenseD435();
};

// Table top: a box of size x size y thickness, top face at `height`, centred above the world
// origin; legs are not modelled. The floor (z = 0) and an optional wall complete the room.
struct TableSpec {
  float length = 1.2f;           // along world x [m]
  float width = 0.8f;            // along world y [m]
  float height = 0.75f;          // top face above the floor [m]
  float thickness = 0.03f;       // [m]
  float floor_half_size = 5.0f;  // the floor is a square of 2 * this [m]
  bool back_wall = false;        // vertical plane y = width / 2 + wall_distance, facing -y
  float wall_distance = 0.5f;    // [m]
};

// What is rendered for an object beyond the plain solid of its `type`. The ground truth stays
// that solid (what a grasp planner should get): the object's extents, not its details.
enum class ObjectForm {
  Plain,       // the solid itself
  Bottle,      // Cylinder: body (radius_bottom), shoulder, neck, cap; height = to the cap's top
  FlatBottle,  // Cube: body with rounded vertical edges and a round cap on top; box_size overall
  Bowl,        // Cone (radius_top > radius_bottom): hollow, open at the top, wall_thickness
  Mug,         // Cylinder: hollow, open at the top, with a handle on its +x side (not in truth)
  LyingCan,    // Cylinder lying on its side: axis horizontal along the object's x (yaw)
};

// One object on the table top. Cube: box_size = (length along its x, width along its y,
// height); round objects: radius_bottom (at the table), radius_top, height (cylinder:
// radius_top == radius_bottom; a lying can: radius_bottom, and height = its length).
struct ObjectSpec {
  ShapeType type = ShapeType::Cube;
  ObjectForm form = ObjectForm::Plain;
  float wall_thickness = 0.004f;  // Bowl, Mug [m]
  Eigen::Vector3f box_size{0.1f, 0.1f, 0.1f};
  float radius_bottom = 0.04f;
  float radius_top = 0.04f;
  float height = 0.1f;
  Eigen::Vector2f position_on_table{0.0f, 0.0f};  // world (x, y) of the bottom centre [m]
  // Its bottom this far above the table top: resting on other objects (a box on a box, a box
  // across two, a can lying on a box) [m]. The scene spec keeps the pile consistent.
  float base_height = 0.0f;
  float yaw = 0.0f;  // about world z [rad]
  std::string name;  // optional label (e.g. "milk-tea box"), copied into the ground truth

  // Top above the table [m].
  float objectHeight() const {
    if (form == ObjectForm::LyingCan) return 2 * radius_bottom;
    return type == ShapeType::Cube ? box_size.z() : height;
  }
  // Half extents of the footprint along world x and y (exact for boxes, discs for round ones).
  Eigen::Vector2f footprintHalfExtents() const;
  // Radius of a disc around position_on_table that contains the footprint.
  float footprintRadius() const;
};

// The paper's test objects (SPEC.md "Ground truth"), standing at the origin with yaw 0.
ObjectSpec milkTeaBox();  // box 0.15 x 0.095 x 0.05
ObjectSpec teapotBox();   // box 0.175 x 0.12 x 0.10
ObjectSpec steelMug();    // cylinder r 0.0415 h 0.16
ObjectSpec beaker();      // truncated cone r 0.03 (bottom) - 0.0375 (top) h 0.18

// Everyday objects (issue 12): the kinds seen failing on real RealSense frames, each with the
// solid expected for it: bottles, cans, markers, mugs and lying cans are cylinders (a mug's
// handle is ignored; a lying can may also be answered by its bounding box), flattened bottles
// and border boxes are boxes, bowls are truncated cones opening upward.
enum class EverydayKind {
  Bottle,        // d 65 h 205 or d 80 h 260 mm
  FlatBottle,    // 50 x 85 x 175 or 65 x 98 x 250 mm, rounded edges, cap
  ShortWideCan,  // d 85 h 33 mm
  Marker,        // d 18 h 140 mm
  SoupCan,       // d 66 h 101 mm
  LyingCan,      // d 66 l 101 mm, axis horizontal
  Bowl,          // d 80 (foot) - 150 (rim) h 65 mm, hollow
  Mug,           // d 82 h 95 mm, hollow, handle
  BorderBox,     // 89 x 38 x 175 mm standing, placed half outside the image
};
constexpr int kEverydayKinds = 9;
const char* everydayKindName(EverydayKind kind);  // also the ObjectSpec's name
// The object of a kind at the origin, yaw 0; `variant` picks one of its sizes (any int).
ObjectSpec everydayObject(EverydayKind kind, int variant = 0);

struct CameraPlacement {
  float distance = 1.0f;   // from the objects' centre on the table top [m]
  float tilt_deg = 40.0f;  // below level
  float yaw_deg = 0.0f;    // heading of the viewing direction about world z
  // The camera looks at this world (x, y) on the table top instead of the objects' centre.
  bool fixed_look_at = false;
  Eigen::Vector2f look_at{0.0f, 0.0f};
};

struct SceneSpec {
  CameraIntrinsics camera;
  CameraPlacement placement;
  TableSpec table;
  std::vector<ObjectSpec> objects;
  NoiseModel noise;
  uint32_t seed = 1;
};

// Ground truth of one object, in the camera optical frame.
struct GroundTruthObject {
  ShapeType type = ShapeType::Cube;
  std::string name;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // centre of the solid
  // Object frame: x along box_size.x, z along the upright axis (pointing up).
  Eigen::Quaternionf orientation = Eigen::Quaternionf::Identity();
  Eigen::Vector3f dimensions = Eigen::Vector3f::Zero();         // cube: edges along x, y, z
  Eigen::Vector3f sorted_dimensions = Eigen::Vector3f::Zero();  // cube: descending
  float radius_bottom = 0.0f;                                   // round objects [m]
  float radius_top = 0.0f;
  float height = 0.0f;  // all types [m] (a lying can: its length along the axis)
  ObjectForm form = ObjectForm::Plain;
  int visible_pixels = 0;  // valid cloud points on this object (after noise)
  // Pixels whose ray meets the object, hidden by others or not (before noise): visible_pixels
  // over this is the fraction of it left visible by the objects in front.
  int unoccluded_pixels = 0;
  bool at_image_border = false;  // some of its valid pixels lie on the image's outer rows / columns
  Eigen::Vector3f axis() const { return orientation * Eigen::Vector3f::UnitZ(); }
};

// Surface labels of the pixels; objects are labelled by their index (>= 0).
enum SurfaceLabel : int { kNoReturn = -1, kFloorLabel = -2, kTableLabel = -3, kWallLabel = -4 };

struct RenderedScene {
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr cloud;    // organised width x height, optical frame
  std::vector<int> labels;                         // per pixel (row-major), SurfaceLabel or object
  std::vector<GroundTruthObject> objects;          // in SceneSpec::objects order
  Plane table_plane;                               // table top, normal up, optical frame
  Eigen::Vector3f up = -Eigen::Vector3f::UnitY();  // world up in the optical frame
  Eigen::Isometry3f world_from_camera = Eigen::Isometry3f::Identity();  // optical -> world
  SceneSpec spec;
};

// World position of the point the camera looks at: the mean of the objects' positions at the
// table-top height (the table centre when there are no objects).
Eigen::Vector3f lookAtPoint(const SceneSpec& spec);
// Pose of the camera optical frame in the world.
Eigen::Isometry3f cameraPose(const SceneSpec& spec);

RenderedScene renderScene(const SceneSpec& spec);

// Ranges for randomScene(); defaults follow the brief of the benchmark.
struct RandomSceneOptions {
  int min_objects = 1;
  int max_objects = 4;
  float min_distance = 0.6f, max_distance = 1.5f;
  float min_tilt_deg = 20.0f, max_tilt_deg = 60.0f;
  float min_yaw_deg = 0.0f, max_yaw_deg = 360.0f;
  float edge_margin = 0.12f;              // footprint to table edge [m]
  float min_gap = 0.02f;                  // between footprint discs [m]
  float paper_object_probability = 0.5f;  // else a random size of a random type
  float image_margin_px = 20.0f;  // every object's centre projects this far inside the image
  CameraIntrinsics camera;
  TableSpec table;
  NoiseModel noise;
};

// A random scene: object count, types, sizes, positions, yaws and the camera are drawn from
// `rng`; the scene seed too. Objects do not overlap, stay inside the table by edge_margin and
// project into the image (the scene is redrawn until they do, up to a fixed number of tries).
SceneSpec randomScene(std::mt19937& rng, const RandomSceneOptions& options = {});
// The paper's four objects together on the table (fixed layout, 2 x 2 around the table centre).
SceneSpec paperScene(const CameraPlacement& placement = {}, const NoiseModel& noise = {},
                     uint32_t seed = 1);

// The paper's four objects in a jittered 2 x 2 grid (random slots and yaws) seen from a random
// camera (0.6-1.5 m, tilt 20-60 deg, any yaw): the benchmark's paper scenes.
SceneSpec jitteredPaperScene(std::mt19937& rng);

// Camera intrinsics and noise model of a sensor.
void setSensor(SceneSpec& spec, SensorModel sensor);

// Everyday objects seen by `sensor` from a steep view: camera 0.5-0.7 m above the table,
// 40-60 deg down, any yaw. A BorderBox, its centre on the image's left, right or bottom border
// (about half of it out of view), and 4 objects of 4 other kinds (a shuffled list: over many
// scenes each kind appears about equally often), centred inside the image. Every object is
// centred 0.4-1.2 m from the camera, and at least 0.1 m beyond the sensor's near limit (0.55 m
// for the Kinect). An object without a free place is left out. Table 1.6 x 1.0 m; half of the
// scenes have a wall 0-0.2 m behind it (where the camera is not beyond the wall).
SceneSpec everydayScene(uint32_t seed, SensorModel sensor);

// Ground truth + scene parameters as a JSON object (hand-written, stable key order).
std::string groundTruthJson(const RenderedScene& scene);
// Writes the cloud as binary PCD / the ground truth as JSON; false on I/O failure.
bool writePcd(const RenderedScene& scene, const std::string& path);
bool writeGroundTruthJson(const RenderedScene& scene, const std::string& path);

}  // namespace sim
}  // namespace tabletop_shapes
