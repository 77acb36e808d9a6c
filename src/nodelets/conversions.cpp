#include "tabletop_shapes/ros/conversions.h"

#include <shape_msgs/SolidPrimitive.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

namespace tabletop_shapes {
namespace bridge {
namespace {

constexpr int kConeSegments = 24;

geometry_msgs::Point toPointMsg(const Eigen::Vector3d& p) {
  geometry_msgs::Point point;
  point.x = p.x();
  point.y = p.y();
  point.z = p.z();
  return point;
}

Eigen::Vector3d fromPointMsg(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }

Eigen::Isometry3d fromPoseMsg(const geometry_msgs::Pose& pose) {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.translation() = fromPointMsg(pose.position);
  transform.linear() = Eigen::Quaterniond(pose.orientation.w, pose.orientation.x,
                                          pose.orientation.y, pose.orientation.z)
                           .normalized()
                           .toRotationMatrix();
  return transform;
}

geometry_msgs::Pose toPoseMsg(const Eigen::Isometry3d& transform) {
  geometry_msgs::Pose pose;
  pose.position = toPointMsg(transform.translation());
  const Eigen::Quaterniond q(transform.rotation());
  pose.orientation.x = q.x();
  pose.orientation.y = q.y();
  pose.orientation.z = q.z();
  pose.orientation.w = q.w();
  return pose;
}

std_msgs::ColorRGBA color(float r, float g, float b, float a) {
  std_msgs::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}

visualization_msgs::Marker marker(const std_msgs::Header& header, const std::string& ns, int id,
                                  int type) {
  visualization_msgs::Marker m;
  m.header = header;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  return m;
}

visualization_msgs::Marker deletion(const std_msgs::Header& header, const std::string& ns, int id) {
  visualization_msgs::Marker m = marker(header, ns, id, visualization_msgs::Marker::CUBE);
  m.action = visualization_msgs::Marker::DELETE;
  return m;
}

// Truncated cone as a triangle list in its own frame (z = axis, centred half-way up).
void coneTriangles(double radius_bottom, double radius_top, double height,
                   std::vector<geometry_msgs::Point>& triangles) {
  const double z0 = -height / 2, z1 = height / 2;
  for (int i = 0; i < kConeSegments; ++i) {
    const double a0 = 2 * kPi * i / kConeSegments, a1 = 2 * kPi * (i + 1) / kConeSegments;
    const Eigen::Vector3d b0(radius_bottom * std::cos(a0), radius_bottom * std::sin(a0), z0);
    const Eigen::Vector3d b1(radius_bottom * std::cos(a1), radius_bottom * std::sin(a1), z0);
    const Eigen::Vector3d t0(radius_top * std::cos(a0), radius_top * std::sin(a0), z1);
    const Eigen::Vector3d t1(radius_top * std::cos(a1), radius_top * std::sin(a1), z1);
    for (const Eigen::Vector3d& p : {b0, b1, t1, b0, t1, t0}) triangles.push_back(toPointMsg(p));
    // caps
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0, 0, z0), b1, b0}) {
      triangles.push_back(toPointMsg(p));
    }
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0, 0, z1), t0, t1}) {
      triangles.push_back(toPointMsg(p));
    }
  }
}

std::string format(const char* pattern, double a, double b = 0, double c = 0) {
  char text[128];
  std::snprintf(text, sizeof(text), pattern, a, b, c);
  return text;
}

}  // namespace

Table toTableMsg(const TableResult& table, float hull_margin, const Eigen::Vector3f& viewpoint,
                 const std_msgs::Header& header) {
  Table msg;
  msg.header = header;
  if (!table.found) {
    msg.reason = table.reason.empty() ? "no table found" : table.reason;
    return msg;
  }
  const Eigen::Vector4f coefficients = table.plane.coefficients();
  for (int i = 0; i < 4; ++i) msg.coefficients[i] = coefficients[i];
  msg.inliers = static_cast<uint32_t>(std::max(table.inliers, 1));
  for (const Eigen::Vector3f& p : table.hull) {
    geometry_msgs::Point32 point;
    point.x = p.x();
    point.y = p.y();
    point.z = p.z();
    msg.hull.points.push_back(point);
  }
  msg.depth_noise_at_one_metre = table.depth_noise_at_one_metre;
  msg.hull_margin = hull_margin;
  msg.viewpoint = toPointMsg(viewpoint.cast<double>());
  return msg;
}

View toViewMsg(const ViewBounds& view, const std_msgs::Header& header) {
  View msg;
  msg.header = header;
  msg.known = view.known;
  msg.min_tan_x = view.min_tan_x;
  msg.max_tan_x = view.max_tan_x;
  msg.min_tan_y = view.min_tan_y;
  msg.max_tan_y = view.max_tan_y;
  msg.pixel_tan = view.pixel_tan;
  msg.min_depth = view.min_depth;
  msg.point_spacing = view.point_spacing;
  return msg;
}

ViewBounds viewFromMsg(const View& msg) {
  ViewBounds view;
  view.known = msg.known;
  view.min_tan_x = msg.min_tan_x;
  view.max_tan_x = msg.max_tan_x;
  view.min_tan_y = msg.min_tan_y;
  view.max_tan_y = msg.max_tan_y;
  view.pixel_tan = msg.pixel_tan;
  view.min_depth = msg.min_depth;
  view.point_spacing = msg.point_spacing;
  return view;
}

Objects skippedFrameObjects(const std_msgs::Header& header, const std::string& reason) {
  Objects objects;
  objects.header = header;
  objects.table.header = header;
  objects.reason = reason;
  return objects;
}

Plane planeFromMsg(const Table& table) {
  Plane plane;
  plane.normal =
      Eigen::Vector3f(table.coefficients[0], table.coefficients[1], table.coefficients[2]);
  plane.d = static_cast<float>(table.coefficients[3]);
  return plane;
}

std::vector<Eigen::Vector3f> hullFromMsg(const Table& table) {
  std::vector<Eigen::Vector3f> hull;
  hull.reserve(table.hull.points.size());
  for (const geometry_msgs::Point32& p : table.hull.points) hull.emplace_back(p.x, p.y, p.z);
  return hull;
}

UnfittedCluster toRejectedMsg(const RejectedCluster& rejected) {
  UnfittedCluster msg;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Point& p : rejected.points->points) sum += p.getVector3fMap().cast<double>();
  if (!rejected.points->empty()) sum /= static_cast<double>(rejected.points->size());
  msg.centroid = toPointMsg(sum);
  msg.points = static_cast<uint32_t>(rejected.points->size());
  msg.reason = rejected.reason;
  return msg;
}

void rejectClustersOffTheTable(const Table& table, const ViewBounds* view,
                               std::vector<CloudPtr>& clusters, Objects& objects) {
  if (!tableFound(table)) return;
  std::vector<RejectedCluster> rejected;
  tabletop_shapes::rejectClustersOffTheTable(
      clusters, planeFromMsg(table), hullFromMsg(table), table.depth_noise_at_one_metre,
      table.hull_margin, fromPointMsg(table.viewpoint).cast<float>(), view, rejected);
  for (const RejectedCluster& r : rejected) objects.rejected.push_back(toRejectedMsg(r));
}

void transformObjects(const Eigen::Isometry3d& target_from_source, const std::string& target_frame,
                      Objects& objects) {
  auto moveHeaderAndPose = [&](std_msgs::Header& header, geometry_msgs::Pose& pose) {
    header.frame_id = target_frame;
    pose = toPoseMsg(target_from_source * fromPoseMsg(pose));
  };
  objects.header.frame_id = target_frame;
  for (Cube& cube : objects.cubes) moveHeaderAndPose(cube.header, cube.pose);
  for (Cylinder& cylinder : objects.cylinders) moveHeaderAndPose(cylinder.header, cylinder.pose);
  for (Cone& cone : objects.cones) moveHeaderAndPose(cone.header, cone.pose);
  for (auto* list : {&objects.unfitted, &objects.rejected}) {
    for (UnfittedCluster& cluster : *list) {
      cluster.centroid = toPointMsg(target_from_source * fromPointMsg(cluster.centroid));
    }
  }
  Table& table = objects.table;
  table.header.frame_id = target_frame;
  if (!tableFound(table)) return;
  // n'.p' + d' = 0 with n' = R n and p' = R p + t: d' = d - n'.t
  const Eigen::Vector3d normal =
      target_from_source.linear() *
      Eigen::Vector3d(table.coefficients[0], table.coefficients[1], table.coefficients[2]);
  const double d = table.coefficients[3] - normal.dot(target_from_source.translation());
  table.coefficients = {normal.x(), normal.y(), normal.z(), d};
  table.viewpoint = toPointMsg(target_from_source * fromPointMsg(table.viewpoint));
  for (geometry_msgs::Point32& p : table.hull.points) {
    const Eigen::Vector3d moved = target_from_source * Eigen::Vector3d(p.x, p.y, p.z);
    p.x = static_cast<float>(moved.x());
    p.y = static_cast<float>(moved.y());
    p.z = static_cast<float>(moved.z());
  }
}

std::string labelText(const Cube& cube) {
  return format(
      cube.bounding_box ? "bounding box %.1f x %.1f x %.1f cm" : "cube %.1f x %.1f x %.1f cm",
      100 * cube.dimensions.x, 100 * cube.dimensions.y, 100 * cube.dimensions.z);
}
std::string labelText(const Cylinder& cylinder) {
  return format("cylinder r %.1f h %.1f cm", 100 * cylinder.radius, 100 * cylinder.height);
}
std::string labelText(const Cone& cone) {
  return format("cone r %.1f-%.1f h %.1f cm", 100 * cone.radius_bottom, 100 * cone.radius_top,
                100 * cone.height);
}

size_t buildMarkers(const Objects& objects, size_t previous_count,
                    visualization_msgs::MarkerArray& markers) {
  using visualization_msgs::Marker;
  const std_msgs::Header& header = objects.header;
  int id = 0;
  // Solid + label; `half_height` puts the label just above the object's top along its axis.
  auto add = [&](const geometry_msgs::Pose& pose, Marker solid, double half_height,
                 const std::string& text) {
    solid.pose = pose;
    markers.markers.push_back(solid);
    Marker label = marker(header, "labels", id, Marker::TEXT_VIEW_FACING);
    const Eigen::Isometry3d object = fromPoseMsg(pose);
    label.pose.position = toPointMsg(object * Eigen::Vector3d(0, 0, half_height + 0.03));
    label.scale.z = 0.025;
    label.color = color(1, 1, 1, 1);
    label.text = text;
    markers.markers.push_back(label);
    ++id;
  };
  for (const Cube& cube : objects.cubes) {
    Marker solid = marker(header, "solids", id, Marker::CUBE);
    solid.scale = cube.dimensions;
    solid.color = color(1.0f, 0.55f, 0.1f, 0.6f);
    add(cube.pose, solid, cube.dimensions.z / 2, labelText(cube));
  }
  for (const Cylinder& cylinder : objects.cylinders) {
    Marker solid = marker(header, "solids", id, Marker::CYLINDER);
    solid.scale.x = solid.scale.y = 2 * cylinder.radius;
    solid.scale.z = cylinder.height;
    solid.color = color(0.2f, 0.45f, 1.0f, 0.6f);
    add(cylinder.pose, solid, cylinder.height / 2, labelText(cylinder));
  }
  for (const Cone& cone : objects.cones) {
    Marker solid = marker(header, "solids", id, Marker::TRIANGLE_LIST);
    coneTriangles(cone.radius_bottom, cone.radius_top, cone.height, solid.points);
    solid.color = color(0.2f, 0.8f, 0.3f, 0.6f);
    add(cone.pose, solid, cone.height / 2, labelText(cone));
  }
  for (const UnfittedCluster& unfitted : objects.unfitted) {
    Marker solid = marker(header, "solids", id, Marker::SPHERE);
    solid.scale.x = solid.scale.y = solid.scale.z = 0.03;
    solid.color = color(0.6f, 0.6f, 0.6f, 0.6f);
    geometry_msgs::Pose pose;
    pose.position = unfitted.centroid;
    pose.orientation.w = 1.0;
    add(pose, solid, 0.0, "unfitted (" + std::to_string(unfitted.points) + " points)");
  }
  const size_t count = static_cast<size_t>(id);
  for (size_t stale = count; stale < previous_count; ++stale) {
    markers.markers.push_back(deletion(header, "solids", static_cast<int>(stale)));
    markers.markers.push_back(deletion(header, "labels", static_cast<int>(stale)));
  }
  const Table& table = objects.table;
  if (objects.table_found && !table.hull.points.empty()) {
    Marker strip = marker(header, "table", 0, Marker::LINE_STRIP);
    strip.scale.x = 0.005;
    strip.color = color(1.0f, 1.0f, 0.2f, 1.0f);
    for (const geometry_msgs::Point32& p : table.hull.points) {
      strip.points.push_back(toPointMsg(Eigen::Vector3d(p.x, p.y, p.z)));
    }
    strip.points.push_back(strip.points.front());  // closed outline
    markers.markers.push_back(strip);
  } else {
    markers.markers.push_back(deletion(header, "table", 0));
  }
  return count;
}

}  // namespace bridge
}  // namespace tabletop_shapes
