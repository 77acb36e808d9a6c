#include "tabletop_shapes/sim/evaluation.h"

#include "tabletop_shapes/core/table_segmentation.h"

#include <pcl/kdtree/kdtree_flann.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

namespace tabletop_shapes {
namespace sim {
namespace {

double frustumVolume(double r0, double r1, double h) {
  return kPi * h * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0;
}

Measure measure(const std::string& name, double estimate, double truth) {
  return {name, estimate, truth, relativeErrorPercent(estimate, truth)};
}

Eigen::Vector3f sortedDescending(Eigen::Vector3f v) {
  std::sort(v.data(), v.data() + 3, std::greater<float>());
  return v;
}

bool isRound(ShapeType type) { return type == ShapeType::Cylinder || type == ShapeType::Cone; }

// Point-in-convex-polygon on the table plane: the hull is ordered, so the point must be on the
// same side of every edge.
bool insideHull(const std::vector<Eigen::Vector3f>& hull, const Eigen::Vector3f& normal,
                const Eigen::Vector3f& p) {
  if (hull.size() < 3) return false;
  int sign = 0;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector3f& a = hull[i];
    const Eigen::Vector3f& b = hull[(i + 1) % hull.size()];
    const float side = normal.dot((b - a).cross(p - a));
    const int s = side > 0 ? 1 : (side < 0 ? -1 : 0);
    if (s == 0) continue;
    if (sign == 0) sign = s;
    if (s != sign) return false;
  }
  return true;
}

double ratio(double numerator, double denominator) {
  return denominator > 0 ? numerator / denominator : 0.0;
}

}  // namespace

double relativeErrorPercent(double estimate, double truth) {
  return std::abs(estimate - truth) / truth * 100.0;
}

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(values.begin(), values.end());
  const double position = fraction * (values.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(position));
  const size_t above = std::min(below + 1, values.size() - 1);
  return values[below] + (position - below) * (values[above] - values[below]);
}

double volume(const ShapeFit& fit) {
  if (!fit.ok) return 0.0;
  switch (fit.type) {
    case ShapeType::Cube:
      return static_cast<double>(fit.dimensions.x()) * fit.dimensions.y() * fit.dimensions.z();
    case ShapeType::Cylinder:
      return frustumVolume(fit.radius, fit.radius, fit.height);
    case ShapeType::Cone:
      return frustumVolume(fit.radius_bottom, fit.radius_top, fit.height);
    case ShapeType::Unknown:
      break;
  }
  return 0.0;
}

double volume(const GroundTruthObject& object) {
  if (object.type == ShapeType::Cube) {
    return static_cast<double>(object.dimensions.x()) * object.dimensions.y() *
           object.dimensions.z();
  }
  return frustumVolume(object.radius_bottom, object.radius_top, object.height);
}

std::vector<Match> matchByCenter(const std::vector<GroundTruthObject>& truth,
                                 const std::vector<ShapeFit>& detections, double max_distance) {
  std::vector<Match> candidates;
  for (size_t t = 0; t < truth.size(); ++t) {
    for (size_t d = 0; d < detections.size(); ++d) {
      const double distance = (truth[t].center - detections[d].center).norm();
      if (distance < max_distance) {
        candidates.push_back({static_cast<int>(t), static_cast<int>(d), distance});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Match& a, const Match& b) { return a.center_distance < b.center_distance; });
  std::vector<bool> truth_used(truth.size()), detection_used(detections.size());
  std::vector<Match> matches;
  for (const Match& m : candidates) {
    if (truth_used[m.truth] || detection_used[m.detection]) continue;
    truth_used[m.truth] = detection_used[m.detection] = true;
    matches.push_back(m);
  }
  return matches;
}

std::vector<Measure> compareToTruth(const GroundTruthObject& truth, const ShapeFit& fit) {
  std::vector<Measure> measures;
  if (!fit.ok) return measures;
  if (truth.type == ShapeType::Cube && fit.type == ShapeType::Cube) {
    const Eigen::Vector3f t = sortedDescending(truth.dimensions);
    const Eigen::Vector3f e = sortedDescending(fit.dimensions);
    measures.push_back(measure("length", e[0], t[0]));
    measures.push_back(measure("width", e[1], t[1]));
    measures.push_back(measure("height", e[2], t[2]));
  } else if (isRound(truth.type) && isRound(fit.type)) {
    const double bottom = fit.type == ShapeType::Cone ? fit.radius_bottom : fit.radius;
    const double top = fit.type == ShapeType::Cone ? fit.radius_top : fit.radius;
    if (truth.type == ShapeType::Cylinder) {
      measures.push_back(measure("radius", (bottom + top) / 2, truth.radius_bottom));
    } else {
      measures.push_back(measure("radius_bottom", bottom, truth.radius_bottom));
      measures.push_back(measure("radius_top", top, truth.radius_top));
    }
    measures.push_back(measure("height", fit.height, truth.height));
  }
  measures.push_back(measure("volume", volume(fit), volume(truth)));
  return measures;
}

namespace {

// Footprint sorted descending, then height.
Eigen::Vector3f footprintAndHeight(float a, float b, float height) {
  return {std::max(a, b), std::min(a, b), height};
}

// A box with edges `dimensions` along the axes of `orientation`: the edge nearest up is its height.
Eigen::Vector3f boxExtents(const Eigen::Quaternionf& orientation, const Eigen::Vector3f& dimensions,
                           const Eigen::Vector3f& up) {
  int vertical = 0;
  (orientation.toRotationMatrix().transpose() * up).cwiseAbs().maxCoeff(&vertical);
  return footprintAndHeight(dimensions[(vertical + 1) % 3], dimensions[(vertical + 2) % 3],
                            dimensions[vertical]);
}

// A round solid of diameter `diameter` and length `length` along an axis `cos_up` from up.
Eigen::Vector3f roundExtents(float diameter, float length, float cos_up) {
  if (std::abs(cos_up) >= std::cos(static_cast<float>(kPi / 4))) {
    return footprintAndHeight(diameter, diameter, length);
  }
  return footprintAndHeight(length, diameter, diameter);
}

// The true object as a box: a round one's bounding box along its own axes.
GroundTruthObject boundingBoxTruth(const GroundTruthObject& truth) {
  GroundTruthObject box = truth;
  box.type = ShapeType::Cube;
  const float diameter = 2 * std::max(truth.radius_bottom, truth.radius_top);
  box.dimensions = {diameter, diameter, truth.height};
  box.sorted_dimensions = sortedDescending(box.dimensions);
  return box;
}

}  // namespace

Eigen::Vector3f solidExtents(const GroundTruthObject& truth, const Eigen::Vector3f& up) {
  if (truth.type == ShapeType::Cube) return boxExtents(truth.orientation, truth.dimensions, up);
  return roundExtents(2 * std::max(truth.radius_bottom, truth.radius_top), truth.height,
                      truth.axis().dot(up));
}

Eigen::Vector3f solidExtents(const ShapeFit& fit, const Eigen::Vector3f& up) {
  switch (fit.type) {
    case ShapeType::Cube:
      return boxExtents(fit.orientation, fit.dimensions, up);
    case ShapeType::Cylinder:
      return roundExtents(2 * fit.radius, fit.height, fit.axis().dot(up));
    case ShapeType::Cone:
      return roundExtents(2 * std::max(fit.radius_bottom, fit.radius_top), fit.height,
                          fit.axis().dot(up));
    case ShapeType::Unknown:
      break;
  }
  return Eigen::Vector3f::Zero();
}

double oversizePercent(const GroundTruthObject& truth, const ShapeFit& fit,
                       const Eigen::Vector3f& up) {
  const Eigen::Vector3f ratio =
      solidExtents(fit, up).cwiseQuotient(solidExtents(truth, up).cwiseMax(1e-6f));
  return 100.0 * (ratio.maxCoeff() - 1.0);
}

bool expectedSolid(const GroundTruthObject& truth, const ShapeFit& fit, const Eigen::Vector3f& up) {
  if (!fit.ok) return false;
  if (truth.type == ShapeType::Cone) {  // and tapering the same way (a bowl opens upward)
    return fit.type == ShapeType::Cone &&
           (fit.radius_top > fit.radius_bottom) == (truth.radius_top > truth.radius_bottom);
  }
  const bool lying_cylinder = fit.type == ShapeType::Cylinder &&
                              std::abs(fit.axis().dot(up)) < std::cos(static_cast<float>(kPi / 4));
  // A standing can or mug fitted by a cylinder on its side is the wrong solid for a grasp.
  if (truth.form != ObjectForm::LyingCan) return fit.type == truth.type && !lying_cylinder;
  return lying_cylinder || fit.type == ShapeType::Cube;
}

std::vector<Measure> dimensionErrors(const GroundTruthObject& truth, const ShapeFit& fit,
                                     const Eigen::Vector3f& up) {
  std::vector<Measure> measures;
  if (!fit.ok) return measures;
  if (expectedSolid(truth, fit, up)) {
    const bool as_box = fit.type == ShapeType::Cube && truth.type != ShapeType::Cube;
    for (const Measure& m : compareToTruth(as_box ? boundingBoxTruth(truth) : truth, fit)) {
      if (m.name != "volume") measures.push_back(m);
    }
    return measures;
  }
  const Eigen::Vector3f e = solidExtents(fit, up), t = solidExtents(truth, up);
  const char* names[] = {"extent length", "extent width", "extent height"};
  for (int i = 0; i < 3; ++i) measures.push_back(measure(names[i], e[i], t[i]));
  return measures;
}

LabelledScore scoreLabelledScene(const pcl::PointCloud<pcl::PointXYZRGBL>& cloud,
                                 const SceneResult& result, int min_object_points,
                                 float table_distance, float cluster_distance) {
  LabelledScore score;
  for (const ShapeFit& fit : result.objects) {
    score.types.push_back(fit.bounding_box ? "bbox"
                                           : shapeTypeName(fit.ok ? fit.type : ShapeType::Unknown));
  }
  // All cluster points in one k-d tree, each tagged with its cluster.
  auto cluster_points = std::make_shared<Cloud>();
  std::vector<int> cluster_of;
  for (size_t c = 0; c < result.clusters.size(); ++c) {
    for (const auto& p : result.clusters[c]->points) {
      cluster_points->push_back(p);
      cluster_of.push_back(static_cast<int>(c));
    }
  }
  pcl::KdTreeFLANN<Point> tree;
  if (!cluster_points->empty()) tree.setInputCloud(cluster_points);

  double table_tp = 0, table_fp = 0, table_fn = 0, object_tp = 0, object_fp = 0, object_fn = 0;
  std::map<int, std::map<int, int>> clusters_of_object;  // object -> cluster -> points
  std::map<int, std::map<int, int>> objects_of_cluster;  // cluster -> object -> points
  std::map<int, int> object_size;
  std::vector<int> index(1);
  std::vector<float> squared_distance(1);
  for (const auto& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || p.label == 0) {
      continue;
    }
    const Eigen::Vector3f v = p.getVector3fMap();
    const bool truly_table = p.label < 10;
    const int object = truly_table ? -1 : static_cast<int>(p.label / 10) - 1;
    const bool said_table = result.table.found &&
                            std::abs(result.table.plane.signedDistance(v)) < table_distance &&
                            insideHull(result.table.hull, result.table.plane.normal, v);
    table_tp += said_table && truly_table;
    table_fp += said_table && !truly_table;
    table_fn += !said_table && truly_table;

    int cluster = -1;
    if (!cluster_points->empty() &&
        tree.nearestKSearch(Point(p.x, p.y, p.z), 1, index, squared_distance) > 0 &&
        squared_distance[0] < cluster_distance * cluster_distance) {
      cluster = cluster_of[index[0]];
    }
    object_tp += cluster >= 0 && !truly_table;
    object_fp += cluster >= 0 && truly_table;
    object_fn += cluster < 0 && !truly_table;
    if (!truly_table) {
      ++object_size[object];
      if (cluster >= 0) {
        ++clusters_of_object[object][cluster];
        ++objects_of_cluster[cluster][object];
      }
    }
  }
  score.table_precision = ratio(table_tp, table_tp + table_fp);
  score.table_recall = ratio(table_tp, table_tp + table_fn);
  score.object_precision = ratio(object_tp, object_tp + object_fp);
  score.object_recall = ratio(object_tp, object_tp + object_fn);

  // Found whole: one cluster holds >= 70 % of the object's points, and >= 70 % of that
  // cluster's labelled object points are this object's (not merged with a neighbour).
  for (const auto& [object, size] : object_size) {
    if (size < min_object_points) continue;
    ++score.labelled_objects;
    const auto& clusters = clusters_of_object[object];
    if (clusters.empty()) continue;
    const auto best = std::max_element(clusters.begin(), clusters.end(),
                                       [](auto& a, auto& b) { return a.second < b.second; });
    int cluster_total = 0;
    for (const auto& entry : objects_of_cluster[best->first]) cluster_total += entry.second;
    if (best->second >= 0.7 * size && best->second >= 0.7 * cluster_total) {
      ++score.objects_found_whole;
    }
  }
  return score;
}

bool labelledTablePlane(const pcl::PointCloud<pcl::PointXYZRGBL>& cloud, Plane& plane) {
  Cloud table;
  std::vector<int> indices;
  for (const auto& p : cloud.points) {
    if (p.label == 0 || p.label >= 10 || !p.getVector3fMap().allFinite()) continue;
    indices.push_back(static_cast<int>(table.size()));
    table.push_back(Point(p.x, p.y, p.z));
  }
  if (!refinePlaneOLS(table, indices, plane)) return false;
  if (plane.d < 0.0f) {  // the camera (the origin) above the table
    plane.normal = -plane.normal;
    plane.d = -plane.d;
  }
  return true;
}

ObjectCounts& ObjectCounts::operator+=(const ObjectCounts& o) {
  objects += o.objects;
  found += o.found;
  pieces += o.pieces;
  junk += o.junk;
  typed += o.typed;
  type_right += o.type_right;
  return *this;
}

namespace {

// A labelled object's points in the table frame (u, v, height): their box and centroid.
struct LabelledBox {
  Eigen::Vector3f low = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f high = Eigen::Vector3f::Constant(-std::numeric_limits<float>::max());
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  int points = 0;
  void add(const Eigen::Vector3f& q) {
    low = low.cwiseMin(q);
    high = high.cwiseMax(q);
    sum += q;
    ++points;
  }
  bool contains(const Eigen::Vector3f& q, float grow) const {
    return (q.array() >= low.array() - grow).all() && (q.array() <= high.array() + grow).all();
  }
};

// An object whose bottom a nearer object hides: below its lowest visible pixel, in at least
// kHiddenBottomShare of its image columns (the camera upright, the table below), the next
// valid pixel shows another object at least kNearer closer to the camera and at least
// kHigherThanItsBottom higher above the table. The object may go on down behind the occluder
// to the table (OSD learn16: a box behind a taller one, seen 17-25 cm up, stands on the table
// for all the data tell); a box resting on a lower one shows the lower one's top at its own
// bottom height, and a box on the table its own bottom edge.
constexpr float kHiddenBottomShare = 0.5f;
constexpr float kNearer = 0.01f;                // [m]
constexpr float kHigherThanItsBottom = 0.015f;  // [m]: depth noise on box tops is < 1 cm

std::set<int> keysWithHiddenBottoms(const pcl::PointCloud<pcl::PointXYZRGBL>& cloud,
                                    const Plane& table,
                                    const std::function<int(uint32_t)>& key_of) {
  std::set<int> hidden_bottoms;
  if (cloud.height < 2) return hidden_bottoms;
  auto valid = [&](const pcl::PointXYZRGBL& p) { return p.getVector3fMap().allFinite(); };
  std::map<int, std::pair<int, int>> columns;  // key -> (columns, columns hidden below)
  for (uint32_t col = 0; col < cloud.width; ++col) {
    for (uint32_t row = 0; row + 1 < cloud.height; ++row) {
      const pcl::PointXYZRGBL& p = cloud.at(col, row);
      if (p.label < 10 || !valid(p)) continue;
      uint32_t below = row + 1;
      while (below < cloud.height && !valid(cloud.at(col, below))) ++below;
      if (below == cloud.height) continue;
      const pcl::PointXYZRGBL& q = cloud.at(col, below);
      const int key = key_of(p.label);
      if (q.label >= 10 && key_of(q.label) == key) continue;  // not its lowest pixel here
      auto& [seen, hidden] = columns[key];
      ++seen;
      hidden += q.label >= 10 && q.getVector3fMap().norm() < p.getVector3fMap().norm() - kNearer &&
                table.signedDistance(q.getVector3fMap()) >
                    table.signedDistance(p.getVector3fMap()) + kHigherThanItsBottom;
    }
  }
  for (const auto& [key, counts] : columns) {
    if (counts.second >= kHiddenBottomShare * counts.first) hidden_bottoms.insert(key);
  }
  return hidden_bottoms;
}

bool rightType(ExpectedShape expected, const ShapeFit& fit) {
  if (!fit.ok) return false;
  return expected == ExpectedShape::Box ? fit.type == ShapeType::Cube : isRound(fit.type);
}

// `boxes`: object key -> its box; `expected_of_key` the expected shape of a key.
ObjectCounts countObjects(const std::map<int, LabelledBox>& boxes,
                          const std::vector<Eigen::Vector3f>& centres,
                          const std::vector<ShapeFit>& detections,
                          const std::function<ExpectedShape(int)>& expected_of_key, float grow) {
  ObjectCounts counts;
  counts.objects = static_cast<int>(boxes.size());
  struct Candidate {
    int key;
    size_t detection;
    float distance;
  };
  std::vector<Candidate> candidates;
  for (const auto& [key, box] : boxes) {
    const Eigen::Vector3f centroid = box.sum / static_cast<float>(box.points);
    for (size_t d = 0; d < centres.size(); ++d) {
      if (box.contains(centres[d], grow))
        candidates.push_back({key, d, (centres[d] - centroid).norm()});
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.distance < b.distance; });
  std::map<int, bool> key_used;
  std::vector<bool> detection_used(centres.size(), false);
  for (const Candidate& c : candidates) {
    if (key_used[c.key] || detection_used[c.detection]) continue;
    key_used[c.key] = detection_used[c.detection] = true;
    ++counts.found;
    const ExpectedShape expected = expected_of_key(c.key);
    if (expected == ExpectedShape::Unknown) continue;
    ++counts.typed;
    counts.type_right += rightType(expected, detections[c.detection]);
  }
  for (size_t d = 0; d < centres.size(); ++d) {
    if (detection_used[d]) continue;
    const bool inside_an_object = std::any_of(boxes.begin(), boxes.end(), [&](const auto& entry) {
      return entry.second.contains(centres[d], grow);
    });
    ++(inside_an_object ? counts.pieces : counts.junk);
  }
  return counts;
}

}  // namespace

LabelledObjectScore scoreLabelledObjects(const pcl::PointCloud<pcl::PointXYZRGBL>& cloud,
                                         const std::vector<ShapeFit>& detections,
                                         const std::function<ExpectedShape(int)>& expected,
                                         float grow) {
  LabelledObjectScore score;
  Plane table;
  if (!labelledTablePlane(cloud, table)) return score;
  const Eigen::Vector3f& n = table.normal;
  Eigen::Vector3f u = Eigen::Vector3f::UnitX() - n.x() * n;  // the camera's x on the table
  if (!(u.norm() > 1e-3f)) u = n.unitOrthogonal();
  u.normalize();
  const Eigen::Vector3f v = n.cross(u);
  auto tableFrame = [&](const Eigen::Vector3f& p) {
    return Eigen::Vector3f(u.dot(p), v.dot(p), table.signedDistance(p));
  };
  std::map<int, LabelledBox> objects, parts;
  for (const auto& p : cloud.points) {
    if (p.label < 10 || !p.getVector3fMap().allFinite()) continue;
    const Eigen::Vector3f q = tableFrame(p.getVector3fMap());
    objects[static_cast<int>(p.label / 10)].add(q);
    parts[static_cast<int>(p.label)].add(q);
  }
  // An object whose bottom another hides may reach down to the table: its fit's centre lies
  // lower than its visible points tell.
  auto reachDownToTheTable = [&](std::map<int, LabelledBox>& boxes,
                                 const std::function<int(uint32_t)>& key_of) {
    for (int key : keysWithHiddenBottoms(cloud, table, key_of))
      boxes[key].low.z() = std::min(boxes[key].low.z(), 0.0f);
  };
  reachDownToTheTable(objects, [](uint32_t label) { return static_cast<int>(label / 10); });
  reachDownToTheTable(parts, [](uint32_t label) { return static_cast<int>(label); });
  std::vector<Eigen::Vector3f> centres;
  for (const ShapeFit& fit : detections) centres.push_back(tableFrame(fit.center));
  score.whole = countObjects(objects, centres, detections, expected, grow);
  score.parts = countObjects(
      parts, centres, detections, [&](int label) { return expected(label / 10); }, grow);
  return score;
}

}  // namespace sim
}  // namespace tabletop_shapes
