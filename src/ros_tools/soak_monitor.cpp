// The figures of `make soak` (scripts/soak): listens to the chain's objects and /diagnostics
// for a given time and prints frames in / out / dropped per stage, the objects messages out by
// kind (with a result, refused as busy at Preprocess, with another reason), the manager's RSS
// at start and end, and the latency (objects received - the cloud's stamp) p50 / p99 / max of
// the frames the chain worked on (busy answers, sent at once, are left out).
// Exit 0 when objects kept coming and memory stayed flat, 1 otherwise, 2 on bad arguments.
//   soak_monitor SECONDS [MAX_RSS_GROWTH_MB]
#include "tabletop_shapes/ros/frame_admission.h"

#include <tabletop_shapes/Objects.h>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

namespace {

const char* const kStages[] = {"preprocess", "table_segmentation", "clustering",
                               "shape_estimation"};

struct Monitor {
  std::mutex mutex;
  std::vector<double> latencies_ms;
  size_t objects = 0, with_reason = 0, busy = 0;
  std::map<std::string, std::map<std::string, double>> diagnostics;  // stage -> key -> value

  void onObjects(const tabletop_shapes::ObjectsConstPtr& msg) {
    const double latency_ms = (ros::Time::now() - msg->header.stamp).toSec() * 1e3;
    std::lock_guard<std::mutex> lock(mutex);
    ++objects;
    if (tabletop_shapes::bridge::isChainBusyReason(msg->reason)) {
      ++busy;
      return;
    }
    if (!msg->reason.empty()) ++with_reason;
    latencies_ms.push_back(latency_ms);
  }
  void onDiagnostics(const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& status : msg->status) {
      for (const char* stage : kStages) {
        const std::string suffix = std::string("/") + stage + ": processing";
        if (status.name.size() < suffix.size() ||
            status.name.compare(status.name.size() - suffix.size(), suffix.size(), suffix) != 0) {
          continue;
        }
        for (const auto& kv : status.values) {
          diagnostics[stage][kv.key] = std::atof(kv.value.c_str());
        }
      }
    }
  }
  double value(const std::string& stage, const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex);
    return diagnostics[stage][key];
  }
};

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t index =
      std::min(values.size() - 1, static_cast<size_t>(p * (values.size() - 1) + 0.5));
  return values[index];
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "soak_monitor", ros::init_options::AnonymousName);
  const double seconds = argc > 1 ? std::atof(argv[1]) : 0.0;
  const double max_growth_mb = argc > 2 ? std::atof(argv[2]) : 100.0;
  if (seconds <= 0.0) {
    std::fprintf(stderr, "usage: soak_monitor SECONDS [MAX_RSS_GROWTH_MB]\n");
    return 2;
  }
  ros::NodeHandle node;
  Monitor monitor;
  ros::Subscriber objects =
      node.subscribe("/tabletop_shapes/objects", 100, &Monitor::onObjects, &monitor);
  ros::Subscriber diagnostics =
      node.subscribe("/diagnostics", 100, &Monitor::onDiagnostics, &monitor);
  ros::AsyncSpinner spinner(1);
  spinner.start();

  // Start once the chain runs: the first objects and a memory figure.
  const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::ok() && ros::WallTime::now() < give_up &&
         !(monitor.objects > 0 && monitor.value("preprocess", "process RSS [MB]") > 0)) {
    ros::WallDuration(0.2).sleep();
  }
  if (monitor.objects == 0) {
    std::fprintf(stderr, "soak: no objects within 60 s\n");
    return 1;
  }
  auto totals = [&](const char* stage) {
    return std::make_tuple(monitor.value(stage, "frames"), monitor.value(stage, "frames skipped"),
                           monitor.value(stage, "frames dropped at input queue"),
                           monitor.value(stage, "frames skipped: chain busy"));
  };
  std::map<std::string, std::tuple<double, double, double, double>> start;
  for (const char* stage : kStages) start[stage] = totals(stage);
  const double rss_start = monitor.value("preprocess", "process RSS [MB]");
  size_t objects_start, busy_start, with_reason_start;
  {
    std::lock_guard<std::mutex> lock(monitor.mutex);
    objects_start = monitor.objects;
    busy_start = monitor.busy;
    with_reason_start = monitor.with_reason;
    monitor.latencies_ms.clear();
  }
  std::printf("soak: %.0f s; manager RSS at start %.1f MB\n", seconds, rss_start);
  std::fflush(stdout);
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  int minute = 0;
  size_t minute_start = 0;  // index into latencies_ms of the minute's first objects message
  while (ros::ok() && ros::WallTime::now() < end) {
    ros::WallDuration(1.0).sleep();
    const double elapsed = seconds - (end - ros::WallTime::now()).toSec();
    if (elapsed >= 60.0 * (minute + 1)) {
      ++minute;
      // Each minute's own latency: a backlog, or stamps that stand still, show as growth here.
      std::vector<double> this_minute;
      size_t objects_now;
      {
        std::lock_guard<std::mutex> lock(monitor.mutex);
        this_minute.assign(monitor.latencies_ms.begin() + minute_start, monitor.latencies_ms.end());
        minute_start = monitor.latencies_ms.size();
        objects_now = monitor.objects;
      }
      std::printf(
          "soak: %3d min, objects %zu (%zu worked on), RSS %.1f MB, latency p50 %.0f ms,"
          " max %.0f ms\n",
          minute, objects_now - objects_start, this_minute.size(),
          monitor.value("preprocess", "process RSS [MB]"), percentile(this_minute, 0.5),
          percentile(this_minute, 1.0));
      std::fflush(stdout);
    }
  }
  ros::WallDuration(1.5).sleep();  // the last diagnostics
  const double rss_end = monitor.value("preprocess", "process RSS [MB]");
  std::lock_guard<std::mutex> lock(monitor.mutex);
  const size_t out = monitor.objects - objects_start;
  const size_t busy = monitor.busy - busy_start,
               with_reason = monitor.with_reason - with_reason_start;
  double in = 0, dropped_total = 0;
  std::printf("soak: %-20s %10s %10s %10s %10s\n", "stage", "processed", "skipped", "busy",
              "dropped");
  for (const char* stage : kStages) {
    const auto& s0 = start[stage];
    const double frames = monitor.diagnostics[stage]["frames"] - std::get<0>(s0);
    const double skipped = monitor.diagnostics[stage]["frames skipped"] - std::get<1>(s0);
    const double dropped =
        monitor.diagnostics[stage]["frames dropped at input queue"] - std::get<2>(s0);
    const double refused =
        monitor.diagnostics[stage]["frames skipped: chain busy"] - std::get<3>(s0);
    if (std::string(stage) == "preprocess") in = frames + skipped + refused + dropped;
    dropped_total += dropped;
    std::printf("soak: %-20s %10.0f %10.0f %10.0f %10.0f\n", stage, frames, skipped, refused,
                dropped);
  }
  std::printf(
      "soak: frames in %.0f (%.1f Hz), objects out %zu: %zu with a result (%.1f Hz), %zu "
      "skipped busy, %zu with another reason; frames without an answer (dropped at queues) %.0f\n",
      in, in / seconds, out, out - busy - with_reason, (out - busy - with_reason) / seconds, busy,
      with_reason, dropped_total);
  std::printf("soak: manager RSS start %.1f MB, end %.1f MB\n", rss_start, rss_end);
  std::printf(
      "soak: latency (objects received - cloud stamp; busy answers left out) p50 %.0f ms, "
      "p99 %.0f ms, max %.0f ms\n",
      percentile(monitor.latencies_ms, 0.5), percentile(monitor.latencies_ms, 0.99),
      percentile(monitor.latencies_ms, 1.0));
  bool ok = true;
  if (out < seconds / 10) {
    std::printf("soak: FAIL: fewer than one objects message per 10 s\n");
    ok = false;
  }
  if (rss_end > rss_start + max_growth_mb) {
    std::printf("soak: FAIL: RSS grew by more than %.0f MB\n", max_growth_mb);
    ok = false;
  }
  std::fflush(stdout);
  return ok ? 0 : 1;
}
