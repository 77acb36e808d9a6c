// tabletop_shapes/Clustering (paper 2.5): Euclidean clusters of the points above the table,
// split where objects stand on each other (concave seams; needs the table plane).
// Subscribes: table (tabletop_shapes/Table) and objects_cloud (pcl::PointCloud<pcl::PointXYZ>),
//   paired by their identical stamps (exact time), as TableSegmentation publishes them
// Publishes, once per frame with the input's header:
//   clusters (pcl::PointCloud<pcl::PointXYZL>): every clustered point, label = cluster index,
//     largest cluster first (label 0); empty when there is none
//   clusters_colored (pcl::PointCloud<pcl::PointXYZRGB>), only while someone subscribes
// The clusters' header.seq numbers the frames published, so that ShapeEstimation counts the
// frames it drops.
// Parameters: cfg/Clustering.cfg (dynamic_reconfigure); ~queue_size (int, 5).
#include "tabletop_shapes/core/clustering.h"
#include "tabletop_shapes/ros/conversions.h"
#include "tabletop_shapes/ros/reconfigure.h"
#include "tabletop_shapes/ros/stage_monitor.h"
#include "tabletop_shapes/ClusteringConfig.h"

#include <dynamic_reconfigure/server.h>
#include <message_filters/subscriber.h>
#include <message_filters/time_synchronizer.h>
#include <nodelet/nodelet.h>
#include <pcl_ros/point_cloud.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>
#include <mutex>

namespace tabletop_shapes {

using LabeledCloud = pcl::PointCloud<pcl::PointXYZL>;
using ColoredCloud = pcl::PointCloud<pcl::PointXYZRGB>;

class ClusteringNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& node = getNodeHandle();
    ros::NodeHandle& private_node = getPrivateNodeHandle();
    // Start-up values are checked before anything holds the nodelet's callback queues: the
    // loader destroys a nodelet whose onInit throws after those queues, and a live timer or
    // subscriber then crashes the process before the refusal is printed.
    bridge::seedCoreDefaults(private_node, {"clustering"});
    monitor_ = std::make_unique<bridge::StageMonitor>(node, getName());
    reconfigure_ = std::make_unique<dynamic_reconfigure::Server<ClusteringConfig>>(
        reconfigure_mutex_, private_node);
    reconfigure_->setCallback([this](ClusteringConfig& config, uint32_t) {
      PipelineParams params;
      std::string error;
      if (!bridge::applyConfig(config, {"clustering"}, params, error)) {
        NODELET_ERROR("rejected parameters: %s", error.c_str());
        return;
      }
      std::lock_guard<std::mutex> lock(params_mutex_);
      params_ = params.clustering;
    });
    clusters_publisher_ = node.advertise<LabeledCloud>("clusters", 5);
    colored_publisher_ = node.advertise<ColoredCloud>("clusters_colored", 1);
    const int queue_size = private_node.param("queue_size", 5);
    table_subscriber_.subscribe(node, "table", queue_size);
    cloud_subscriber_.subscribe(node, "objects_cloud", queue_size);
    monitor_->expectInput<Table>(table_subscriber_.getSubscriber());
    monitor_->expectInput<Cloud>(cloud_subscriber_.getSubscriber());
    synchronizer_ = std::make_unique<message_filters::TimeSynchronizer<Table, Cloud>>(
        table_subscriber_, cloud_subscriber_, 2 * queue_size);
    synchronizer_->registerCallback(boost::bind(&ClusteringNodelet::onFrame, this,
                                                boost::placeholders::_1, boost::placeholders::_2));
  }

  void onFrame(const TableConstPtr& table, const boost::shared_ptr<const Cloud>& cloud) {
    const bridge::Stopwatch stopwatch;
    monitor_->countInput(cloud.get());
    monitor_->countSequence(cloud->header.seq);
    ClusteringParams params;
    {
      std::lock_guard<std::mutex> lock(params_mutex_);
      params = params_;
    }
    // Without a table there are no object points; the plane only enables the split.
    const Plane plane = bridge::planeFromMsg(*table);
    const std::vector<CloudPtr> clusters =
        extractClusters(pcl::pcl_ptr(cloud), params, bridge::tableFound(*table) ? &plane : nullptr);

    auto labeled = boost::make_shared<LabeledCloud>();
    labeled->header = cloud->header;
    labeled->header.seq = ++published_;
    size_t points = 0;
    for (const CloudPtr& cluster : clusters) points += cluster->size();
    labeled->reserve(points);
    for (size_t label = 0; label < clusters.size(); ++label) {
      for (const Point& p : clusters[label]->points) {
        pcl::PointXYZL point;
        point.getVector3fMap() = p.getVector3fMap();
        point.label = static_cast<uint32_t>(label);
        labeled->push_back(point);
      }
    }
    if (colored_publisher_.getNumSubscribers() > 0) publishColored(*labeled);
    const size_t points_out = labeled->size();
    boost::shared_ptr<const LabeledCloud> shared = labeled;
    bridge::markPublished(shared);
    clusters_publisher_.publish(shared);
    monitor_->frameDone(stopwatch.milliseconds(), cloud->size(), points_out);
  }

  void publishColored(const LabeledCloud& labeled) {
    // A few well separated colours, repeated.
    static const uint8_t kPalette[][3] = {
        {230, 25, 75},  {60, 180, 75},  {255, 225, 25}, {0, 130, 200},  {245, 130, 48},
        {145, 30, 180}, {70, 240, 240}, {240, 50, 230}, {210, 245, 60}, {250, 190, 212}};
    constexpr size_t kColors = sizeof(kPalette) / sizeof(kPalette[0]);
    auto colored = boost::make_shared<ColoredCloud>();
    colored->header = labeled.header;
    colored->reserve(labeled.size());
    for (const pcl::PointXYZL& p : labeled.points) {
      const uint8_t* rgb = kPalette[p.label % kColors];
      pcl::PointXYZRGB point(rgb[0], rgb[1], rgb[2]);
      point.getVector3fMap() = p.getVector3fMap();
      colored->push_back(point);
    }
    colored_publisher_.publish(boost::shared_ptr<const ColoredCloud>(colored));
  }

  std::unique_ptr<bridge::StageMonitor> monitor_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<ClusteringConfig>> reconfigure_;
  std::mutex params_mutex_;
  ClusteringParams params_;
  uint32_t published_ = 0;  // frames published: the seq of ShapeEstimation's input
  ros::Publisher clusters_publisher_, colored_publisher_;
  message_filters::Subscriber<Table> table_subscriber_;
  message_filters::Subscriber<Cloud> cloud_subscriber_;
  std::unique_ptr<message_filters::TimeSynchronizer<Table, Cloud>> synchronizer_;
};

}  // namespace tabletop_shapes

PLUGINLIB_EXPORT_CLASS(tabletop_shapes::ClusteringNodelet, nodelet::Nodelet)
