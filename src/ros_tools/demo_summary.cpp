// The table printed by scripts/demo: waits for a few tabletop_shapes/Objects messages and prints
// the objects of the last one (type, dimensions, position in cm), each beside the true object
// when a ground-truth file written by `render_oni --json` is given. Exits 0 once the frames
// arrived, 1 when none arrived in time, 2 on bad arguments.
//   demo_summary [--topic /tabletop_shapes/objects] [--frames 5] [--timeout 25] [--truth F.json]
#include <tabletop_shapes/Objects.h>

#include <geometry_msgs/Point.h>
#include <ros/ros.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace {

const char* kUsage =
    "usage: demo_summary [--topic T] [--frames N] [--timeout S] [--truth FILE.json]";

// One object, found or true, in the units printed (metres; cm on output).
struct Row {
  std::string type;                // cube, cylinder, cone
  std::vector<double> dimensions;  // cube: edges sorted descending; cylinder: r, h; cone: r, R, h
  double x = 0, y = 0, z = 0;      // centre of the solid, camera frame
};

std::string dimensionsText(const Row& row) {
  const std::vector<double>& d = row.dimensions;
  char text[64] = "";
  if (row.type == "cube" && d.size() == 3) {
    std::snprintf(text, sizeof text, "%5.1f x %4.1f x %4.1f", 100 * d[0], 100 * d[1], 100 * d[2]);
  } else if (row.type == "cylinder" && d.size() == 2) {
    std::snprintf(text, sizeof text, "r %4.1f, h %4.1f", 100 * d[0], 100 * d[1]);
  } else if (row.type == "cone" && d.size() == 3) {
    std::snprintf(text, sizeof text, "r %3.1f-%3.1f, h %4.1f", 100 * d[0], 100 * d[1], 100 * d[2]);
  }
  return text;
}

std::string positionText(const Row& row) {
  char text[64];
  std::snprintf(text, sizeof text, "%5.1f %5.1f %5.1f", 100 * row.x, 100 * row.y, 100 * row.z);
  return text;
}

std::vector<Row> rowsOf(const tabletop_shapes::Objects& objects) {
  std::vector<Row> rows;
  for (const auto& cube : objects.cubes) {
    std::vector<double> edges = {cube.dimensions.x, cube.dimensions.y, cube.dimensions.z};
    std::sort(edges.rbegin(), edges.rend());
    const auto& p = cube.pose.position;
    rows.push_back({"cube", edges, p.x, p.y, p.z});
  }
  for (const auto& cylinder : objects.cylinders) {
    const auto& p = cylinder.pose.position;
    rows.push_back({"cylinder", {cylinder.radius, cylinder.height}, p.x, p.y, p.z});
  }
  for (const auto& cone : objects.cones) {
    const auto& p = cone.pose.position;
    rows.push_back({"cone", {cone.radius_bottom, cone.radius_top, cone.height}, p.x, p.y, p.z});
  }
  return rows;
}

std::vector<double> numbers(const std::string& text) {
  std::vector<double> values;
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) values.push_back(std::strtod(item.c_str(), nullptr));
  return values;
}

// The objects of a ground-truth file of render_oni --json (the renderer's own stable layout:
// one object per `{"type": ...}` block, arrays without nesting), or an empty list.
std::vector<Row> readTruth(const std::string& path, std::string& names) {
  std::ifstream file(path);
  const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  std::vector<Row> rows;
  const size_t objects = text.find("\"objects\"");
  if (objects == std::string::npos) return rows;
  auto field = [](const std::string& block, const std::string& key) {
    const std::regex pattern("\"" + key + "\": (\\[[^\\]]*\\]|\"[^\"]*\"|[-0-9.e+]+)");
    std::smatch match;
    if (!std::regex_search(block, match, pattern)) return std::string();
    std::string value = match[1];
    if (!value.empty() && (value.front() == '[' || value.front() == '"')) {
      value = value.substr(1, value.size() - 2);
    }
    return value;
  };
  size_t start = text.find("{\"type\"", objects);
  while (start != std::string::npos) {
    const size_t end = text.find('}', start);
    const std::string block = text.substr(start, end - start);
    Row row;
    row.type = field(block, "type");
    const std::vector<double> centre = numbers(field(block, "center"));
    if (centre.size() == 3) {
      row.x = centre[0];
      row.y = centre[1];
      row.z = centre[2];
    }
    const double height = std::strtod(field(block, "height").c_str(), nullptr);
    if (row.type == "cube") {
      row.dimensions = numbers(field(block, "sorted_dimensions"));
    } else if (row.type == "cylinder") {
      row.dimensions = {std::strtod(field(block, "radius_bottom").c_str(), nullptr), height};
    } else {
      row.dimensions = {std::strtod(field(block, "radius_bottom").c_str(), nullptr),
                        std::strtod(field(block, "radius_top").c_str(), nullptr), height};
    }
    names += (names.empty() ? "" : ", ") + field(block, "name");
    rows.push_back(row);
    start = text.find("{\"type\"", end);
  }
  return rows;
}

double distance(const Row& a, const Row& b) {
  return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) +
                   (a.z - b.z) * (a.z - b.z));
}

// Pairs every found object with the nearest unused true object of its type (greedy by distance).
std::vector<int> match(const std::vector<Row>& found, const std::vector<Row>& truth) {
  std::vector<int> partner(found.size(), -1);
  std::vector<bool> used(truth.size(), false);
  for (;;) {
    double best = std::numeric_limits<double>::infinity();
    size_t best_f = 0, best_t = 0;
    for (size_t f = 0; f < found.size(); ++f) {
      if (partner[f] >= 0) continue;
      for (size_t t = 0; t < truth.size(); ++t) {
        if (used[t] || truth[t].type != found[f].type) continue;
        if (distance(found[f], truth[t]) < best) {
          best = distance(found[f], truth[t]);
          best_f = f;
          best_t = t;
        }
      }
    }
    if (!std::isfinite(best)) return partner;
    partner[best_f] = static_cast<int>(best_t);
    used[best_t] = true;
  }
}

void printTable(const tabletop_shapes::Objects& last, const std::vector<Row>& truth) {
  const std::vector<Row> found = rowsOf(last);
  const std::vector<int> partner = match(found, truth);
  std::printf("\n%-9s %-22s %-22s %-18s %-18s %s\n", "object", "dimensions [cm]",
              truth.empty() ? "" : "true [cm]", "centre x y z [cm]",
              truth.empty() ? "" : "true centre [cm]", truth.empty() ? "" : "off [cm]");
  for (size_t f = 0; f < found.size(); ++f) {
    const Row* true_row = partner[f] >= 0 ? &truth[partner[f]] : nullptr;
    std::printf("%-9s %-22s %-22s %-18s %-18s", found[f].type.c_str(),
                dimensionsText(found[f]).c_str(),
                true_row ? dimensionsText(*true_row).c_str() : (truth.empty() ? "" : "(none)"),
                positionText(found[f]).c_str(), true_row ? positionText(*true_row).c_str() : "");
    if (true_row) std::printf(" %4.1f", 100 * distance(found[f], *true_row));
    std::printf("\n");
  }
  std::vector<bool> found_truth(truth.size(), false);
  for (int p : partner) {
    if (p >= 0) found_truth[p] = true;
  }
  for (size_t t = 0; t < truth.size(); ++t) {
    if (found_truth[t]) continue;
    std::printf("%-9s %-22s %-22s %-18s %-18s\n", "(missed)", "", dimensionsText(truth[t]).c_str(),
                "", positionText(truth[t]).c_str());
  }
  for (const auto& unfitted : last.unfitted) {
    std::printf("unfitted  %u points at %.1f %.1f %.1f cm: %s\n", unfitted.points,
                100 * unfitted.centroid.x, 100 * unfitted.centroid.y, 100 * unfitted.centroid.z,
                unfitted.reason.c_str());
  }
  for (const auto& rejected : last.rejected) {
    std::printf("rejected  %u points at %.1f %.1f %.1f cm: %s\n", rejected.points,
                100 * rejected.centroid.x, 100 * rejected.centroid.y, 100 * rejected.centroid.z,
                rejected.reason.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "demo_summary", ros::init_options::AnonymousName);
  std::string topic = "/tabletop_shapes/objects", truth_path;
  int frames = 5;
  double timeout = 25;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "demo_summary: '%s' needs a value; %s\n", arg.c_str(), kUsage);
      return 2;
    }
    const std::string value = argv[++i];
    if (arg == "--topic") {
      topic = value;
    } else if (arg == "--truth") {
      truth_path = value;
    } else if (arg == "--frames") {
      frames = std::max(1, std::atoi(value.c_str()));
    } else if (arg == "--timeout") {
      timeout = std::atof(value.c_str());
    } else {
      std::fprintf(stderr, "demo_summary: unknown argument '%s'; %s\n", arg.c_str(), kUsage);
      return 2;
    }
  }
  std::string names;
  const std::vector<Row> truth =
      truth_path.empty() ? std::vector<Row>{} : readTruth(truth_path, names);
  if (!truth_path.empty() && truth.empty()) {
    std::fprintf(stderr, "demo_summary: no objects in the ground truth %s\n", truth_path.c_str());
  }

  // The table is the output: no "Connected to master" line above it.
  if (ros::console::set_logger_level("ros.roscpp", ros::console::levels::Warn)) {
    ros::console::notifyLoggerLevelsChanged();
  }
  // Subscribing retries forever while there is no master: the timeout starts before it.
  const ros::WallTime start = ros::WallTime::now();
  while (!ros::master::check()) {
    if (!ros::ok() || (ros::WallTime::now() - start).toSec() >= timeout) {
      std::fprintf(stderr, "demo_summary: no ROS master at %s within %.0f s\n",
                   ros::master::getURI().c_str(), timeout);
      return 1;
    }
    ros::WallDuration(0.2).sleep();
  }
  ros::NodeHandle node;
  std::vector<tabletop_shapes::Objects> received;
  ros::Subscriber subscriber = node.subscribe<tabletop_shapes::Objects>(
      topic, 10, [&](const tabletop_shapes::ObjectsConstPtr& message) {
        received.push_back(*message);
        const size_t n = message->cubes.size() + message->cylinders.size() + message->cones.size();
        std::printf("  frame %zu: %s, %zu object(s) (%.1f s)\n", received.size(),
                    message->table_found ? "table" : "no table", n,
                    (ros::WallTime::now() - start).toSec());
        std::fflush(stdout);
      });
  std::printf("Waiting for %d frames on %s ...\n", frames, topic.c_str());
  std::fflush(stdout);
  while (ros::ok() && static_cast<int>(received.size()) < frames &&
         (ros::WallTime::now() - start).toSec() < timeout) {
    ros::spinOnce();
    ros::WallDuration(0.02).sleep();
  }
  if (received.empty()) {
    std::fprintf(stderr, "demo_summary: no message on %s within %.0f s\n", topic.c_str(), timeout);
    return 1;
  }
  const tabletop_shapes::Objects& last = received.back();
  std::printf(
      "\nFrame %zu: table %s; %zu cube(s), %zu cylinder(s), %zu cone(s), %zu unfitted; "
      "positions in %s\n",
      received.size(), last.table_found ? "found" : "NOT found", last.cubes.size(),
      last.cylinders.size(), last.cones.size(), last.unfitted.size(), last.header.frame_id.c_str());
  if (!truth.empty()) std::printf("True objects (rendered): %s\n", names.c_str());
  printTable(last, truth);
  return 0;
}
