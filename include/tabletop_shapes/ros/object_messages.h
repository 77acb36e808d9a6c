// Core ShapeFit -> Cube / Cylinder / Cone / UnfittedCluster messages. Header-only, so that the
// ROS tools (the bag writer's ground truth) build the very same messages as the nodelets.
#pragma once

#include "tabletop_shapes/core/types.h"

#include <geometry_msgs/Pose.h>
#include <shape_msgs/SolidPrimitive.h>
#include <std_msgs/Header.h>
#include <tabletop_shapes/Objects.h>

#include <algorithm>

namespace tabletop_shapes {
namespace bridge {

inline geometry_msgs::Pose toPoseMsg(const Eigen::Vector3f& position,
                                     const Eigen::Quaternionf& orientation) {
  const Eigen::Quaternionf q = orientation.normalized();
  geometry_msgs::Pose pose;
  pose.position.x = position.x();
  pose.position.y = position.y();
  pose.position.z = position.z();
  pose.orientation.x = q.x();
  pose.orientation.y = q.y();
  pose.orientation.z = q.z();
  pose.orientation.w = q.w();
  return pose;
}

// Truncation flags of a cylinder or cone message (ShapeFit::lower_bound: radius, radius, height).
template <typename RoundMsg>
void setTruncation(const ShapeFit& fit, RoundMsg& msg) {
  msg.truncated = fit.truncated;
  msg.radius_lower_bound = fit.lower_bound[0];
  msg.height_lower_bound = fit.lower_bound[2];
}

// Appends `fit` to the list of its type (cubes, cylinders, cones, or unfitted with the reason).
inline void appendObject(const ShapeFit& fit, const std_msgs::Header& header, Objects& objects) {
  const geometry_msgs::Pose pose = toPoseMsg(fit.center, fit.orientation);
  if (!fit.ok || fit.type == ShapeType::Unknown) {
    UnfittedCluster unfitted;
    unfitted.centroid.x = fit.center.x();
    unfitted.centroid.y = fit.center.y();
    unfitted.centroid.z = fit.center.z();
    unfitted.points = static_cast<uint32_t>(std::max(fit.points, 0));
    unfitted.reason = fit.reason.empty() ? "no model fits" : fit.reason;
    objects.unfitted.push_back(unfitted);
  } else if (fit.type == ShapeType::Cube) {
    Cube cube;
    cube.header = header;
    cube.pose = pose;
    cube.dimensions.x = fit.dimensions.x();
    cube.dimensions.y = fit.dimensions.y();
    cube.dimensions.z = fit.dimensions.z();
    cube.faces_seen = static_cast<uint8_t>(fit.faces_seen);
    cube.points = static_cast<uint32_t>(fit.points);
    cube.rmse = fit.rmse;
    cube.bounding_box = fit.bounding_box;
    if (fit.bounding_box) cube.reason = fit.reason;
    cube.truncated = fit.truncated;
    for (int i = 0; i < 3; ++i) cube.dimensions_lower_bound[i] = fit.lower_bound[i];
    cube.primitive.type = shape_msgs::SolidPrimitive::BOX;
    cube.primitive.dimensions = {fit.dimensions.x(), fit.dimensions.y(), fit.dimensions.z()};
    objects.cubes.push_back(cube);
  } else if (fit.type == ShapeType::Cylinder) {
    Cylinder cylinder;
    cylinder.header = header;
    cylinder.pose = pose;
    cylinder.radius = fit.radius;
    cylinder.height = fit.height;
    cylinder.points = static_cast<uint32_t>(fit.points);
    cylinder.rmse = fit.rmse;
    setTruncation(fit, cylinder);
    cylinder.primitive.type = shape_msgs::SolidPrimitive::CYLINDER;
    cylinder.primitive.dimensions = {fit.height, fit.radius};
    objects.cylinders.push_back(cylinder);
  } else {
    Cone cone;
    cone.header = header;
    cone.pose = pose;
    cone.radius_bottom = fit.radius_bottom;
    cone.radius_top = fit.radius_top;
    cone.height = fit.height;
    cone.points = static_cast<uint32_t>(fit.points);
    cone.rmse = fit.rmse;
    setTruncation(fit, cone);
    cone.primitive.type = shape_msgs::SolidPrimitive::CYLINDER;
    cone.primitive.dimensions = {fit.height, 0.5 * (fit.radius_bottom + fit.radius_top)};
    objects.cones.push_back(cone);
  }
}

}  // namespace bridge
}  // namespace tabletop_shapes
