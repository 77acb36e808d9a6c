// speed_feed: the camera of `make benchmark-speed`. Publishes organised XYZRGB clouds (a
// PointCloud2, as a camera driver in another process would) of the benchmark's rendered scenes
// or of PCD files, each stamped with the wall time it is published, and listens for the
// chain's answer to pace itself:
//   --rate 0   (as fast as the chain takes them) the next cloud goes out when the answer to the
//              last one arrived (or after --timeout seconds);
//   --rate HZ  a cloud every 1/HZ s, whatever the chain does (frames it cannot take are lost).
// Writes one CSV line per measured frame (after --warmup frames): stamp_us, answer_us (-1: no
// answer). An answer is a message on --ack whose stamp lies in [stamp, stamp + 0.1 s) (pcl_ros
// stamps its i-th cluster i ms after the input).
//   speed_feed --out CSV (--objects N [--width W --height H] | --pcd FILE...) [--frames N]
//     [--warmup N] [--rate HZ] [--timeout S] [--topic T] [--ack T] [--ack-type objects|xyz]
//     [--xyz]   (x y z only, 16 bytes a point, as openni2_launch's depth/points; else x y z rgb,
//                32 bytes a point, as depth_registered/points)
#include "tabletop_shapes/Objects.h"
#include "tabletop_shapes/sim/speed_scenes.h"

#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <set>
#include <string>
#include <vector>

namespace {

namespace sim = tabletop_shapes::sim;

struct Options {
  std::string out, topic = "/camera/depth_registered/points";
  std::string ack = "/tabletop_shapes/objects", ack_type = "objects";
  std::string frame_id = "camera_rgb_optical_frame";
  std::vector<std::string> pcds;
  int objects = 0, width = 640, height = 480, frames = 300, warmup = 10, renders = 4;
  double rate = 0.0, timeout = 2.0;
  bool xyz_only = false;
};

bool parse(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (arg == "--out")
      o.out = value();
    else if (arg == "--topic")
      o.topic = value();
    else if (arg == "--ack")
      o.ack = value();
    else if (arg == "--ack-type")
      o.ack_type = value();
    else if (arg == "--frame-id")
      o.frame_id = value();
    else if (arg == "--objects")
      o.objects = std::atoi(value().c_str());
    else if (arg == "--width")
      o.width = std::atoi(value().c_str());
    else if (arg == "--height")
      o.height = std::atoi(value().c_str());
    else if (arg == "--frames")
      o.frames = std::atoi(value().c_str());
    else if (arg == "--warmup")
      o.warmup = std::atoi(value().c_str());
    else if (arg == "--renders")
      o.renders = std::atoi(value().c_str());
    else if (arg == "--rate")
      o.rate = std::atof(value().c_str());
    else if (arg == "--timeout")
      o.timeout = std::atof(value().c_str());
    else if (arg == "--pcd")
      o.pcds.push_back(value());
    else if (arg == "--xyz")
      o.xyz_only = true;
    else
      return false;
  }
  return !o.out.empty() && (o.objects > 0 || !o.pcds.empty()) && o.frames > 0 &&
         (o.ack_type == "objects" || o.ack_type == "xyz");
}

// Answers received: their stamps [us].
class Answers {
 public:
  void add(int64_t stamp_us) {
    const int64_t now = static_cast<int64_t>(ros::WallTime::now().toNSec() / 1000);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      arrivals_.emplace_back(stamp_us, now);
    }
    arrived_.notify_all();
  }
  // Arrival of the first answer to `stamp_us`, or -1.
  int64_t answerTo(int64_t stamp_us) {
    std::lock_guard<std::mutex> lock(mutex_);
    return answerToLocked(stamp_us);
  }
  // Sleeps until the answer to `stamp_us` arrives or `timeout` passes. Woken by the answer, not
  // polling: a camera uses no CPU between frames, and a feed that polled every 0.2 ms took
  // ~5 % of a core from the chain it measures on a 2-core machine.
  void waitFor(int64_t stamp_us, double timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    arrived_.wait_for(lock, std::chrono::duration<double>(timeout),
                      [&] { return answerToLocked(stamp_us) >= 0 || !ros::ok(); });
  }

 private:
  int64_t answerToLocked(int64_t stamp_us) const {
    for (const auto& [stamp, arrival] : arrivals_) {
      if (stamp >= stamp_us && stamp < stamp_us + 100000) return arrival;
    }
    return -1;
  }

  std::mutex mutex_;
  std::condition_variable arrived_;
  std::vector<std::pair<int64_t, int64_t>> arrivals_;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "speed_feed", ros::init_options::AnonymousName);
  Options options;
  if (!parse(argc, argv, options)) {
    std::fprintf(stderr,
                 "usage: speed_feed --out CSV (--objects N [--width W --height H] | --pcd FILE...)"
                 " [--frames N] [--warmup N] [--rate HZ] [--timeout S] [--topic T] [--ack T]"
                 " [--ack-type objects|xyz] [--xyz]\n");
    return 2;
  }
  // The clouds, converted once: publishing costs only the serialisation, as for a driver.
  std::vector<sensor_msgs::PointCloud2> clouds;
  auto addCloud = [&](const pcl::PointCloud<pcl::PointXYZRGB>& cloud) {
    clouds.emplace_back();
    if (!options.xyz_only) {
      pcl::toROSMsg(cloud, clouds.back());
      return;
    }
    pcl::PointCloud<pcl::PointXYZ> xyz;
    pcl::copyPointCloud(cloud, xyz);  // keeps the organised layout and the NaNs
    pcl::toROSMsg(xyz, clouds.back());
  };
  if (options.objects > 0) {
    for (int r = 0; r < options.renders; ++r) {
      const sim::RenderedScene scene = sim::renderScene(sim::speedScene(
          options.objects, options.width, options.height, static_cast<uint32_t>(r + 1)));
      addCloud(*scene.cloud);
    }
  } else {
    for (const std::string& path : options.pcds) {
      pcl::PointCloud<pcl::PointXYZRGB> cloud;
      if (pcl::io::loadPCDFile(path, cloud) < 0) {
        std::fprintf(stderr, "speed_feed: cannot read %s\n", path.c_str());
        return 2;
      }
      addCloud(cloud);
    }
  }

  ros::NodeHandle node;
  Answers answers;
  ros::Subscriber subscriber;
  if (options.ack_type == "objects") {
    subscriber = node.subscribe<tabletop_shapes::Objects>(
        options.ack, 50, [&](const tabletop_shapes::Objects::ConstPtr& m) {
          answers.add(static_cast<int64_t>(m->header.stamp.toNSec() / 1000));
        });
  } else {
    subscriber = node.subscribe<pcl::PointCloud<pcl::PointXYZ>>(
        options.ack, 50, [&](const boost::shared_ptr<const pcl::PointCloud<pcl::PointXYZ>>& m) {
          answers.add(static_cast<int64_t>(m->header.stamp));
        });
  }
  ros::Publisher publisher = node.advertise<sensor_msgs::PointCloud2>(options.topic, 2);
  ros::AsyncSpinner spinner(1);
  spinner.start();

  // Both ends connected before the first frame.
  const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::ok() && (publisher.getNumSubscribers() == 0 || subscriber.getNumPublishers() == 0)) {
    if (ros::WallTime::now() > give_up) {
      std::fprintf(stderr, "speed_feed: nobody subscribes to %s or publishes %s\n",
                   options.topic.c_str(), options.ack.c_str());
      return 1;
    }
    ros::WallDuration(0.05).sleep();
  }
  ros::WallDuration(0.5).sleep();

  std::vector<int64_t> stamps;
  const int total = options.warmup + options.frames;
  const ros::WallDuration period(options.rate > 0 ? 1.0 / options.rate : 0.0);
  ros::WallTime next = ros::WallTime::now();
  for (int f = 0; f < total && ros::ok(); ++f) {
    if (options.rate > 0) {
      ros::WallTime now = ros::WallTime::now();
      if (next > now) (next - now).sleep();
      next += period;
    }
    sensor_msgs::PointCloud2& cloud = clouds[static_cast<size_t>(f) % clouds.size()];
    cloud.header.frame_id = options.frame_id;
    // Whole microseconds: PCL headers keep no finer stamps, and answers are matched by stamp.
    const int64_t stamp_us = static_cast<int64_t>(ros::WallTime::now().toNSec() / 1000);
    cloud.header.stamp.fromNSec(static_cast<uint64_t>(stamp_us) * 1000);
    publisher.publish(cloud);
    if (f >= options.warmup) stamps.push_back(stamp_us);
    if (options.rate <= 0) answers.waitFor(stamp_us, options.timeout);
    if ((f + 1) % 10 == 0 || f + 1 == total) {
      std::fprintf(stderr, "\r  frame %d / %d", f + 1, total);
      std::fflush(stderr);
    }
  }
  ros::WallDuration(std::max(1.0, options.timeout)).sleep();  // the last answers
  std::fprintf(stderr, "\r%*s\r", 30, "");

  FILE* file = std::fopen(options.out.c_str(), "w");
  if (!file) return 1;
  std::fprintf(file, "stamp_us,answer_us\n");
  for (const int64_t stamp : stamps) {
    std::fprintf(file, "%lld,%lld\n", static_cast<long long>(stamp),
                 static_cast<long long>(answers.answerTo(stamp)));
  }
  std::fclose(file);
  spinner.stop();
  return 0;
}
