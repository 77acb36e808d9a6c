// Scoring the pipeline against ground truth: rendered scenes (known solids) and labelled real
// scenes (OSD per-point labels). Shared by the accuracy benchmark and the accuracy tests.
#pragma once

#include "tabletop_shapes/core/pipeline.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <functional>

namespace tabletop_shapes {
namespace sim {

// Eq. 17: |estimate - truth| / truth * 100 %.
double relativeErrorPercent(double estimate, double truth);
double percentile(std::vector<double> values, double fraction);  // 0.5 = median; NaN if empty

double volume(const ShapeFit& fit);              // of the fitted solid [m^3]; 0 if not ok
double volume(const GroundTruthObject& object);  // [m^3]

// A matched pair of a true object and a detection (indices into the two lists).
struct Match {
  int truth = -1;
  int detection = -1;
  double center_distance = 0.0;
};
// Greedy, closest pairs first, each side used once, centres closer than max_distance.
std::vector<Match> matchByCenter(const std::vector<GroundTruthObject>& truth,
                                 const std::vector<ShapeFit>& detections, double max_distance);

// One compared measure: e.g. "length" of a box, "radius" of a cylinder.
struct Measure {
  std::string name;
  double estimate = 0.0, truth = 0.0, error_percent = 0.0;
};
// The measures of the paper's Tables 2-3 for a true object and its fit. Boxes: length, width,
// height (edges sorted length >= width >= height on both sides), volume. Cylinders: radius,
// height, volume. Cones: radius_bottom, radius_top, height, volume. A round object fitted by
// the other round model is compared through its radii (a cylinder's radius stands for both
// radii of a cone, a cone's mean radius for a cylinder's); a box against a round fit (or the
// reverse) gets only its volume compared.
std::vector<Measure> compareToTruth(const GroundTruthObject& truth, const ShapeFit& fit);

// ---- everyday objects (issue 12): the solid expected for each kind ----

// The solid's extents in the table frame (`up` in its frame): footprint length >= width, then
// height. A true lying can: (length, diameter, diameter); a fitted box: the edge nearest up is
// its height; a fitted round solid whose axis is within 45 deg of up stands (diameter of its
// wider end twice, height), else it lies (as the can).
Eigen::Vector3f solidExtents(const GroundTruthObject& truth, const Eigen::Vector3f& up);
Eigen::Vector3f solidExtents(const ShapeFit& fit, const Eigen::Vector3f& up);
// The largest fitted extent relative to the true one, minus 1, in percent (the issue's
// "never more than 20 % larger in any dimension"); negative when the fit is smaller in all.
double oversizePercent(const GroundTruthObject& truth, const ShapeFit& fit,
                       const Eigen::Vector3f& up);
// The fit is the solid expected for the true object: its type, a cone tapering the same way
// (a bowl opens upward), a standing cylinder upright (axis within 45 deg of up), and a lying
// can a cylinder lying down (axis more than 45 deg from up) or its bounding box.
bool expectedSolid(const GroundTruthObject& truth, const ShapeFit& fit, const Eigen::Vector3f& up);
// Dimension errors (eq. 17, no volume): the measures of compareToTruth when the solid is the
// expected one (a lying can's box against the can's bounding box), else the extents of both
// solids ("extent length", "extent width", "extent height").
std::vector<Measure> dimensionErrors(const GroundTruthObject& truth, const ShapeFit& fit,
                                     const Eigen::Vector3f& up);

// ---- labelled real scenes (OSD: label 1-9 table, label / 10 - 1 = object index) ----
struct LabelledScore {
  double table_precision = 0.0, table_recall = 0.0;    // per point, vs labels 1-9
  double object_precision = 0.0, object_recall = 0.0;  // per point, vs labels >= 10
  int labelled_objects = 0;        // objects with at least min_object_points points
  int objects_found_whole = 0;     // of those: one cluster holds most of it, and mostly it
  std::vector<std::string> types;  // the types given to the clusters
};
// `cloud` is the raw labelled cloud given to the pipeline, `result` what it found;
// a raw point belongs to the table when it lies within `table_distance` of the plane and inside
// the hull, to a cluster when a cluster point is within `cluster_distance` of it.
LabelledScore scoreLabelledScene(const pcl::PointCloud<pcl::PointXYZRGBL>& cloud,
                                 const SceneResult& result, int min_object_points = 500,
                                 float table_distance = 0.015f, float cluster_distance = 0.01f);

// ---- labelled real scenes scored by object: found, pieces, junk, type ----
// The table frame of a labelled scene: the plane fitted (OLS) to the points labelled table,
// its normal towards the camera; false when fewer than 3 table points.
bool labelledTablePlane(const pcl::PointCloud<pcl::PointXYZRGBL>& cloud, Plane& plane);

// What a labelled object (or part) is, for the type score: Unknown when not known.
// Round: a cylinder or a cone is right.
enum class ExpectedShape { Unknown, Box, Round };

// Counts over the objects of one or more scenes. An object is found when a detection's centre
// lies in the box of its labelled points (in the table frame: height along the normal, the
// in-plane axes from the camera's x axis) grown by `grow` on every side; each detection finds
// at most one object, each object is found by at most one detection (closest to its labelled
// centroid first). A detection that finds nothing is a piece when its centre lies in some
// object's grown box, else junk. An object whose lowest visible pixels lie just above a nearer
// object seen higher (its bottom hidden behind it) has its box reach down to the table.
struct ObjectCounts {
  int objects = 0, found = 0, pieces = 0, junk = 0;
  int typed = 0, type_right = 0;  // found objects whose expected shape is known; of those right
  ObjectCounts& operator+=(const ObjectCounts& o);
};
struct LabelledObjectScore {
  ObjectCounts whole;  // objects = label decades (label / 10)
  ObjectCounts parts;  // each label its own segment (disjoint visible parts of one object)
};
// `expected(decade)` gives the expected shape of object `decade` (label / 10).
LabelledObjectScore scoreLabelledObjects(const pcl::PointCloud<pcl::PointXYZRGBL>& cloud,
                                         const std::vector<ShapeFit>& detections,
                                         const std::function<ExpectedShape(int)>& expected,
                                         float grow = 0.03f);

}  // namespace sim
}  // namespace tabletop_shapes
