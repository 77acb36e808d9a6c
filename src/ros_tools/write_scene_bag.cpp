// Writes a small rosbag for replay tests and demos, either from rendered scenes (the paper's
// objects, random ones, or everyday objects on a Kinect v1 or RealSense D435)
// (tabletop_shapes_sim), or from a PCD file:
//   <topic>        sensor_msgs/PointCloud2, organised, x y z (+ rgb for rendered scenes)
//   /ground_truth  tabletop_shapes/Objects with the same stamp: the true solids in the cloud's
//                  frame (rendered; `truncated` when some of the object's pixels lie on the
//                  image's outer rows or columns), or one UnfittedCluster per labelled object (OSD
//                  PCD files: labels 20-29 = object 0, 30-39 = object 1, ...)
//   /tf_static     (rendered only, latched) <up_frame> -> <frame_id>: the world frame, +z up
// Stamps are whole microseconds (what PCL headers keep), so pairing by stamp is exact.
#include "tabletop_shapes/ros/conversions.h"
#include "tabletop_shapes/sim/scene_renderer.h"

#include <geometry_msgs/TransformStamped.h>
#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>
#include <rosbag/bag.h>
#include <sensor_msgs/PointCloud2.h>
#include <pcl_conversions/pcl_conversions.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <map>
#include <string>

namespace {

namespace sim = tabletop_shapes::sim;
namespace bridge = tabletop_shapes::bridge;

const char* kUsage =
    "usage: write_scene_bag --out BAG [--scene paper|random|everyday] [--sensor kinect|realsense]\n"
    "         [--seed N] [--frames N]\n"
    "         [--rate HZ] [--qvga] [--distance M] [--tilt DEG] [--yaw DEG] [--no-tf]\n"
    "         [--topic T] [--frame-id F] [--up-frame U] [--pcd FILE]\n"
    "  Rendered scenes (default: the paper's four objects) get a new noise seed per frame;\n"
    "  --pcd FILE repeats that cloud instead (x y z, and OSD labels as ground truth).";

struct Options {
  std::string out, scene = "paper", pcd;
  std::string topic = "/camera/depth_registered/points";
  std::string frame_id = "camera_rgb_optical_frame", up_frame = "base_link";
  int frames = 3;
  uint32_t seed = 1;
  double rate = 2.0, distance = NAN, tilt = NAN, yaw = NAN;
  bool qvga = false, tf = true;
  sim::SensorModel sensor = sim::SensorModel::KinectV1;  // of the everyday scene
};

bool parse(int argc, char** argv, Options& o, std::string& error) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto text = [&](std::string& value) {
      if (i + 1 >= argc) return false;
      value = argv[++i];
      return true;
    };
    auto number = [&](double& value, double lo, double hi) {
      if (i + 1 >= argc) return false;
      char* end = nullptr;
      value = std::strtod(argv[++i], &end);
      return end && *end == '\0' && value >= lo && value <= hi;
    };
    double value = 0;
    bool ok = true;
    if (arg == "--out")
      ok = text(o.out);
    else if (arg == "--scene")
      ok = text(o.scene) && (o.scene == "paper" || o.scene == "random" || o.scene == "everyday");
    else if (arg == "--sensor") {
      std::string name;
      ok = text(name) && sim::parseSensorName(name, o.sensor);
    } else if (arg == "--pcd")
      ok = text(o.pcd);
    else if (arg == "--topic")
      ok = text(o.topic);
    else if (arg == "--frame-id")
      ok = text(o.frame_id);
    else if (arg == "--up-frame")
      ok = text(o.up_frame);
    else if (arg == "--frames")
      ok = number(value, 1, 1000) && (o.frames = value, true);
    else if (arg == "--seed")
      ok = number(value, 0, 4294967295.0) && (o.seed = value, true);
    else if (arg == "--rate")
      ok = number(o.rate, 0.01, 100);
    else if (arg == "--distance")
      ok = number(o.distance, 0.3, 5.0);
    else if (arg == "--tilt")
      ok = number(o.tilt, 0.0, 90.0);
    else if (arg == "--yaw")
      ok = number(o.yaw, -360.0, 360.0);
    else if (arg == "--qvga")
      o.qvga = true;
    else if (arg == "--no-tf")
      o.tf = false;
    else
      ok = false;
    if (!ok) {
      error = "bad or incomplete argument '" + arg + "'";
      return false;
    }
  }
  if (o.out.empty()) error = "--out BAG is required";
  return error.empty();
}

// Organised, in PCL's layout (x y z [rgb], 16 / 32 bytes a point), stamp kept exactly.
template <typename PointT>
sensor_msgs::PointCloud2 toCloudMsg(const pcl::PointCloud<PointT>& cloud,
                                    const std_msgs::Header& header) {
  sensor_msgs::PointCloud2 msg;
  pcl::toROSMsg(cloud, msg);
  msg.header = header;
  return msg;
}

tabletop_shapes::Objects groundTruth(const sim::RenderedScene& scene,
                                     const std_msgs::Header& header) {
  tabletop_shapes::Objects objects;
  objects.header = header;
  objects.table_found = true;
  objects.table.header = header;
  const Eigen::Vector4f plane = scene.table_plane.coefficients();
  for (int i = 0; i < 4; ++i) objects.table.coefficients[i] = plane[i];
  objects.table.inliers = 1;
  for (const sim::GroundTruthObject& truth : scene.objects) {
    tabletop_shapes::ShapeFit fit;
    fit.type = truth.type;
    fit.ok = true;
    fit.center = truth.center;
    fit.orientation = truth.orientation;
    fit.dimensions = truth.dimensions;
    fit.radius = truth.radius_bottom;
    fit.radius_bottom = truth.radius_bottom;
    fit.radius_top = truth.radius_top;
    fit.height = truth.height;
    fit.points = truth.visible_pixels;
    fit.truncated = truth.at_image_border;  // which extents are lower bounds is the fit's matter
    bridge::appendObject(fit, header, objects);
  }
  return objects;
}

tabletop_shapes::Objects osdGroundTruth(const pcl::PointCloud<pcl::PointXYZL>& cloud,
                                        const std_msgs::Header& header) {
  std::map<uint32_t, std::pair<Eigen::Vector3d, uint32_t>> sums;  // object -> (sum, count)
  for (const pcl::PointXYZL& p : cloud.points) {
    if (p.label < 20 || !std::isfinite(p.z)) continue;
    auto& entry =
        sums.emplace(p.label / 10 - 1, std::make_pair(Eigen::Vector3d::Zero(), 0u)).first->second;
    entry.first += p.getVector3fMap().cast<double>();
    ++entry.second;
  }
  tabletop_shapes::Objects objects;
  objects.header = header;
  for (const auto& [index, entry] : sums) {
    tabletop_shapes::UnfittedCluster object;
    object.centroid.x = entry.first.x() / entry.second;
    object.centroid.y = entry.first.y() / entry.second;
    object.centroid.z = entry.first.z() / entry.second;
    object.points = entry.second;
    object.reason = "OSD object " + std::to_string(index) + " (labelled, type unknown)";
    objects.unfitted.push_back(object);
  }
  return objects;
}

tf2_msgs::TFMessage upTransform(const sim::RenderedScene& scene, const Options& o,
                                const ros::Time& stamp) {
  geometry_msgs::TransformStamped transform;
  transform.header.stamp = stamp;
  transform.header.frame_id = o.up_frame;
  transform.child_frame_id = o.frame_id;
  const Eigen::Vector3f t = scene.world_from_camera.translation();
  const Eigen::Quaternionf q(scene.world_from_camera.rotation());
  transform.transform.translation.x = t.x();
  transform.transform.translation.y = t.y();
  transform.transform.translation.z = t.z();
  transform.transform.rotation.x = q.x();
  transform.transform.rotation.y = q.y();
  transform.transform.rotation.z = q.z();
  transform.transform.rotation.w = q.w();
  tf2_msgs::TFMessage message;
  message.transforms.push_back(transform);
  return message;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  std::string error;
  if (!parse(argc, argv, o, error)) {
    std::cerr << "write_scene_bag: " << error << "\n" << kUsage << "\n";
    return 2;
  }
  ros::Time::init();
  rosbag::Bag bag;
  try {
    bag.open(o.out, rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    std::cerr << "write_scene_bag: cannot write " << o.out << ": " << e.what() << "\n";
    return 1;
  }
  const ros::Time start(1700000000, 0);
  auto latched = boost::make_shared<ros::M_string>();
  (*latched)["latching"] = "1";
  (*latched)["callerid"] = "/write_scene_bag";
  // A custom connection header replaces rosbag's own: it must name the type itself.
  (*latched)["type"] = ros::message_traits::datatype<tf2_msgs::TFMessage>();
  (*latched)["md5sum"] = ros::message_traits::md5sum<tf2_msgs::TFMessage>();
  (*latched)["message_definition"] = ros::message_traits::definition<tf2_msgs::TFMessage>();

  pcl::PointCloud<pcl::PointXYZL> pcd;
  if (!o.pcd.empty() && pcl::io::loadPCDFile(o.pcd, pcd) < 0) {
    std::cerr << "write_scene_bag: cannot read " << o.pcd << "\n";
    return 1;
  }
  std::mt19937 rng(o.seed);
  sim::SceneSpec spec;
  if (o.pcd.empty()) {
    spec = o.scene == "paper"      ? sim::paperScene(sim::CameraPlacement{1.0f, 40.0f, 90.0f})
           : o.scene == "everyday" ? sim::everydayScene(o.seed, o.sensor)
                                   : sim::randomScene(rng);
    if (!std::isnan(o.distance)) spec.placement.distance = static_cast<float>(o.distance);
    if (!std::isnan(o.tilt)) spec.placement.tilt_deg = static_cast<float>(o.tilt);
    if (!std::isnan(o.yaw)) spec.placement.yaw_deg = static_cast<float>(o.yaw);
    if (o.qvga) {
      spec.camera.width = 320;
      spec.camera.height = 240;
      spec.camera.fx = spec.camera.fy = 287.9f;
      spec.camera.cx = 159.5f;
      spec.camera.cy = 119.5f;
    }
  }
  size_t bytes = 0;
  for (int frame = 0; frame < o.frames; ++frame) {
    // Whole microseconds: the stamp survives the PCL header unchanged.
    const ros::Time stamp = start + ros::Duration(std::round(1e6 * frame / o.rate) * 1e-6);
    std_msgs::Header header;
    header.stamp = stamp;
    header.frame_id = o.frame_id;
    header.seq = frame;
    if (!o.pcd.empty()) {
      pcl::PointCloud<pcl::PointXYZ> xyz;
      pcl::copyPointCloud(pcd, xyz);
      const sensor_msgs::PointCloud2 cloud = toCloudMsg(xyz, header);
      bag.write(o.topic, stamp, cloud);
      bag.write("/ground_truth", stamp, osdGroundTruth(pcd, header));
      bytes += cloud.data.size();
      continue;
    }
    spec.seed = o.seed + frame;  // new sensor noise every frame
    const sim::RenderedScene scene = sim::renderScene(spec);
    if (o.tf && frame == 0) {
      bag.write("/tf_static", stamp, upTransform(scene, o, stamp), latched);
    }
    const sensor_msgs::PointCloud2 cloud = toCloudMsg(*scene.cloud, header);
    bag.write(o.topic, stamp, cloud);
    bag.write("/ground_truth", stamp, groundTruth(scene, header));
    bytes += cloud.data.size();
  }
  bag.close();
  std::cout << "wrote " << o.frames << " frames (" << bytes / 1e6 << " MB of points) to " << o.out
            << "\n";
  return 0;
}
