// tabletop_shapes/ShapeEstimation (paper 3): a box, cylinder or truncated cone per cluster.
// Subscribes: table (tabletop_shapes/Table) and clusters (pcl::PointCloud<pcl::PointXYZL>),
//   paired by their identical stamps (exact time); view (tabletop_shapes/View) from
//   Preprocess, taken by the same stamp: objects cut by the image border come out `truncated`
//   with their lower-bound extents flagged (a frame without its view: none is flagged, and a
//   WARN on /diagnostics says so).
// Publishes, once per frame (also when nothing was found):
//   objects (tabletop_shapes/Objects); `reason` says why there is no result (no table, no
//     transform to output_frame; then in the cloud's frame). Clusters along the table hull's
//     edge (a wall's foot: core table_edge.h) are not fitted but listed in `rejected`. Preprocess
//     and TableSegmentation publish it too for the frames they skip, so every frame taken in gets
//     one.
//   markers (visualization_msgs/MarkerArray): solids, labels, table hull; stale ones deleted
//   cubes / cylinders / cones (tabletop_shapes/Cube, Cylinder, Cone): one message per object,
//     only while someone subscribes
// Parameters: cfg/ShapeEstimation.cfg (dynamic_reconfigure);
//   ~output_frame (string, "": the cloud's frame): results transformed with tf2 at the frame's
//     own stamp; a missing transform skips the frame with a throttled warning; stamps going
//     back (a looped bag) are warned about (ros/frame_transforms.h)
//   ~tf_timeout (double, 0.1 s), ~queue_size (int, 5)
#include "tabletop_shapes/core/object_fitting.h"
#include "tabletop_shapes/ros/answer_publisher.h"
#include "tabletop_shapes/ros/conversions.h"
#include "tabletop_shapes/ros/frame_transforms.h"
#include "tabletop_shapes/ros/reconfigure.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/ShapeEstimationConfig.h"

#include <dynamic_reconfigure/server.h>
#include <message_filters/subscriber.h>
#include <message_filters/time_synchronizer.h>
#include <nodelet/nodelet.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>

#include <deque>
#include <memory>
#include <mutex>

namespace tabletop_shapes {

using LabeledCloud = pcl::PointCloud<pcl::PointXYZL>;

class ShapeEstimationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& node = getNodeHandle();
    ros::NodeHandle& private_node = getPrivateNodeHandle();
    // Start-up values are checked before anything holds the nodelet's callback queues: the
    // loader destroys a nodelet whose onInit throws after those queues, and a live timer or
    // subscriber then crashes the process before the refusal is printed.
    const std::vector<std::string> stages{"normals",  "predictor", "cube",
                                          "cylinder", "cone",      "shapes"};
    bridge::seedCoreDefaults(private_node, stages);
    monitor_ = std::make_unique<bridge::StageMonitor>(node, getName());
    output_frame_ = private_node.param<std::string>("output_frame", "");
    if (!output_frame_.empty()) {
      transforms_ = std::make_unique<bridge::FrameTransforms>(
          ros::Duration(private_node.param("tf_timeout", 0.1)), bridge::warnThrough(*monitor_));
      transforms_->listen(node);
    }
    reconfigure_ = std::make_unique<dynamic_reconfigure::Server<ShapeEstimationConfig>>(
        reconfigure_mutex_, private_node);
    reconfigure_->setCallback([this, stages](ShapeEstimationConfig& config, uint32_t) {
      PipelineParams params;
      std::string error;
      if (!bridge::applyConfig(config, stages, params, error)) {
        NODELET_ERROR("rejected parameters: %s", error.c_str());
        return;
      }
      std::lock_guard<std::mutex> lock(params_mutex_);
      params_ = params.shapes;
    });

    objects_publisher_ = bridge::advertiseAnswers(node);
    markers_publisher_ = node.advertise<visualization_msgs::MarkerArray>("markers", 5);
    cubes_publisher_ = node.advertise<Cube>("cubes", 10);
    cylinders_publisher_ = node.advertise<Cylinder>("cylinders", 10);
    cones_publisher_ = node.advertise<Cone>("cones", 10);

    const int queue_size = private_node.param("queue_size", 5);
    view_subscriber_ = node.subscribe("view", kViewsKept, &ShapeEstimationNodelet::onView, this);
    table_subscriber_.subscribe(node, "table", queue_size);
    clusters_subscriber_.subscribe(node, "clusters", queue_size);
    monitor_->expectInput<Table>(table_subscriber_.getSubscriber());
    monitor_->expectInput<LabeledCloud>(clusters_subscriber_.getSubscriber());
    synchronizer_ = std::make_unique<message_filters::TimeSynchronizer<Table, LabeledCloud>>(
        table_subscriber_, clusters_subscriber_, 2 * queue_size);
    synchronizer_->registerCallback(boost::bind(&ShapeEstimationNodelet::onFrame, this,
                                                boost::placeholders::_1, boost::placeholders::_2));
  }

  // Views arrive before their frame's clusters (Preprocess publishes the view first, and the
  // frame passes two stages after it): kept by stamp until the frame comes.
  void onView(const ViewConstPtr& view) {
    std::lock_guard<std::mutex> lock(views_mutex_);
    views_.push_back(view);
    while (views_.size() > kViewsKept) views_.pop_front();
  }

  // The view of the frame stamped `stamp`; false when it did not come (then `view` stays
  // unknown: nothing is flagged).
  bool viewOf(const ros::Time& stamp, ViewBounds& view) {
    std::lock_guard<std::mutex> lock(views_mutex_);
    for (auto it = views_.rbegin(); it != views_.rend(); ++it) {
      if ((*it)->header.stamp == stamp) {
        view = bridge::viewFromMsg(**it);
        return true;
      }
    }
    return false;
  }

  void onFrame(const TableConstPtr& table, const boost::shared_ptr<const LabeledCloud>& clusters) {
    const bridge::Stopwatch stopwatch;
    monitor_->countInput(clusters.get());
    monitor_->countSequence(clusters->header.seq);
    {
      std::lock_guard<std::mutex> lock(params_mutex_);
      estimator_.setParams(params_);
    }
    // Shared from the start: published by pointer, a consumer in the same manager takes it
    // without serialisation or copy.
    const boost::shared_ptr<Objects> shared = boost::make_shared<Objects>();
    Objects& objects = *shared;
    objects.header = pcl_conversions::fromPCL(clusters->header);
    objects.table = *table;
    objects.table_found = bridge::tableFound(*table);
    if (!objects.table_found) objects.reason = "no table: " + table->reason;
    if (objects.table_found) {
      std::vector<CloudPtr> parts = splitClusters(*clusters);
      const Plane table_plane = bridge::planeFromMsg(*table);
      ViewBounds view;  // unknown for an unorganised input cloud: nothing is cut then
      const bool view_came = viewOf(objects.header.stamp, view);
      monitor_->setWarning("view", view_came ? ""
                                             : "no view (image bounds) of the frame on " +
                                                   view_subscriber_.getTopic() +
                                                   ": objects cut by the image border are not "
                                                   "flagged truncated");
      // Pipeline runs this rule right after clustering; here the table message brings what it
      // needs (depth noise, hull_margin, viewpoint), and the view what is beyond the image.
      bridge::rejectClustersOffTheTable(*table, &view, parts, objects);
      const std::vector<ShapeFit> fits = fitObjects(estimator_, table_plane, view, parts);
      for (const ShapeFit& fit : fits) {
        bridge::appendObject(fit, objects.header, objects);
      }
    }
    if (!output_frame_.empty() && output_frame_ != objects.header.frame_id) {
      try {
        bridge::transformObjects(
            transforms_->lookup(output_frame_, objects.header.frame_id, objects.header.stamp),
            output_frame_, objects);
      } catch (const tf2::TransformException& error) {
        const std::string reason = "no transform to output_frame '" + output_frame_ + "' from '" +
                                   objects.header.frame_id + "': " + error.what();
        // tf's text holds times: throttle on the frames, not on the whole text.
        monitor_->frameSkipped(reason, {bridge::Problem::Level::Warn, "skipping frame: " + reason,
                                        "no transform to " + output_frame_});
        bridge::publishAnswer(objects_publisher_,
                              bridge::skippedFrameObjects(objects.header, reason));
        return;
      }
    }
    publish(shared);
    monitor_->frameDone(stopwatch.milliseconds(), clusters->size(),
                        objects.cubes.size() + objects.cylinders.size() + objects.cones.size());
  }

  static std::vector<CloudPtr> splitClusters(const LabeledCloud& labeled) {
    // Sizes first: each cluster's points are copied once, into a buffer of the right size.
    std::vector<size_t> sizes;
    for (const pcl::PointXYZL& p : labeled.points) {
      if (p.label >= labeled.size()) continue;  // not from Clustering: labels are 0..n-1
      if (sizes.size() <= p.label) sizes.resize(p.label + 1, 0);
      ++sizes[p.label];
    }
    std::vector<CloudPtr> clusters(sizes.size());
    for (size_t label = 0; label < sizes.size(); ++label) {
      clusters[label] = std::make_shared<Cloud>();
      clusters[label]->header = labeled.header;
      clusters[label]->reserve(sizes[label]);
    }
    for (const pcl::PointXYZL& p : labeled.points) {
      if (p.label < sizes.size()) clusters[p.label]->push_back(Point(p.x, p.y, p.z));
    }
    return clusters;
  }

  // `shared` is not changed after this.
  void publish(const boost::shared_ptr<const Objects>& shared) {
    const Objects& objects = *shared;
    visualization_msgs::MarkerArray markers;
    marker_count_ = bridge::buildMarkers(objects, marker_count_, markers);
    bridge::publishAnswer(objects_publisher_, shared);
    markers_publisher_.publish(markers);
    if (cubes_publisher_.getNumSubscribers() > 0) {
      for (const Cube& cube : objects.cubes) cubes_publisher_.publish(cube);
    }
    if (cylinders_publisher_.getNumSubscribers() > 0) {
      for (const Cylinder& cylinder : objects.cylinders) cylinders_publisher_.publish(cylinder);
    }
    if (cones_publisher_.getNumSubscribers() > 0) {
      for (const Cone& cone : objects.cones) cones_publisher_.publish(cone);
    }
  }

  // Views kept for the frames in flight (a few at 30 Hz; the stages between take ~0.1-0.3 s).
  static constexpr size_t kViewsKept = 30;

  std::unique_ptr<bridge::StageMonitor> monitor_;
  std::mutex views_mutex_;
  std::deque<ViewConstPtr> views_;
  ros::Subscriber view_subscriber_;
  std::string output_frame_;
  std::unique_ptr<bridge::FrameTransforms> transforms_;  // with output_frame only
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<ShapeEstimationConfig>> reconfigure_;
  std::mutex params_mutex_;
  ShapeEstimatorParams params_;
  ShapeEstimator estimator_;
  size_t marker_count_ = 0;  // objects shown by the last MarkerArray
  ros::Publisher objects_publisher_, markers_publisher_;
  ros::Publisher cubes_publisher_, cylinders_publisher_, cones_publisher_;
  message_filters::Subscriber<Table> table_subscriber_;
  message_filters::Subscriber<LabeledCloud> clusters_subscriber_;
  std::unique_ptr<message_filters::TimeSynchronizer<Table, LabeledCloud>> synchronizer_;
};

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::ShapeEstimationNodelet, nodelet::Nodelet)
