// check_pipeline_launch: pipeline.launch's checks before any node starts. roslaunch runs it as
// a <param command=...> while it reads the file, so a failure (exit 1, the reason on stderr)
// stops the whole launch at once, instead of a nodelet failing to load into a manager that
// then runs empty.
//   check_pipeline_launch --ns NS --up TEXT --up-frame FRAME --auto-up true|false
//                         [--check-namespace true|false]
// Checks:
//   - up: auto (or empty), X,Y,Z or [x, y, z] (the core's parseUp, as estimate_shapes --up),
//     and not both up and up_frame (or auto_up);
//   - the namespace is free: live nodes under /NS/ on the master of ROS_MASTER_URI mean another
//     pipeline runs there, and a second one would shut it down (one node per name); no master
//     running means nothing can be busy (roslaunch then starts one).
// Prints the up setting as the TableSegmentation nodelet reads it (auto or [x, y, z]).
#include "tabletop_shapes/core/up_direction.h"

#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <iostream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

struct Failure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

bool parseBool(const std::string& option, const std::string& text) {
  if (text == "true" || text == "True" || text == "1") return true;
  if (text == "false" || text == "False" || text == "0" || text.empty()) return false;
  throw Failure(option + " wants true or false, got '" + text + "'");
}

// True when the node answers at its XML-RPC address: a node killed without unregistering
// stays listed by the master, and must not block a new launch.
bool nodeAlive(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = "/check_pipeline_launch";
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return false;
  std::string host, path;
  uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return false;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue call, answer;
  call[0] = "/check_pipeline_launch";
  const bool alive = client.execute("getPid", call, answer) && !client.isFault();
  client.close();
  return alive;
}

// Live nodes whose names lie under `ns` (/name).
std::vector<std::string> nodesInNamespace(const std::string& ns) {
  const std::string prefix = ns.back() == '/' ? ns : ns + "/";
  std::vector<std::string> nodes, busy;
  if (!ros::master::check() || !ros::master::getNodes(nodes)) return busy;
  for (const std::string& node : nodes) {
    if (node.rfind(prefix, 0) == 0 && nodeAlive(node)) busy.push_back(node);
  }
  return busy;
}

int run(int argc, char** argv) {
  std::map<std::string, std::string> options = {{"--ns", "tabletop_shapes"},
                                                {"--up", ""},
                                                {"--up-frame", ""},
                                                {"--auto-up", "false"},
                                                {"--check-namespace", "true"}};
  for (int i = 1; i < argc; ++i) {
    const std::string option = argv[i];
    if (!options.count(option)) throw Failure("unknown option " + option);
    if (i + 1 >= argc) throw Failure(option + " needs a value");
    options[option] = argv[++i];
  }
  tabletop_shapes::UpSetting up;
  std::string error;
  if (!tabletop_shapes::parseUp(options["--up"], up, error)) throw Failure(error);
  if (!up.automatic && !options["--up-frame"].empty()) {
    throw Failure("up:=" + options["--up"] + " and up_frame:=" + options["--up-frame"] +
                  " both given: give one of them");
  }
  if (!up.automatic && parseBool("auto_up", options["--auto-up"])) {
    throw Failure("up:=" + options["--up"] + " and auto_up:=true both given: give one of them");
  }
  if (parseBool("check_namespace", options["--check-namespace"])) {
    std::string ns = options["--ns"];
    if (ns.empty() || ns.front() != '/') ns = "/" + ns;
    const std::vector<std::string> busy = nodesInNamespace(ns);
    if (!busy.empty()) {
      std::string names;
      for (const std::string& node : busy) names += (names.empty() ? "" : ", ") + node;
      throw Failure("namespace " + ns + " is busy: " + names + " already run on " +
                    ros::master::getURI() +
                    " (another pipeline.launch?). A second pipeline there would shut the first "
                    "down (one node per name): give it its own namespace, e.g. ns:=" +
                    ns.substr(1) + "_2, or stop the first");
    }
  }
  std::cout << (up.automatic ? std::string("auto") : tabletop_shapes::formatUp(up.vector));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // NoRosout and no node registration: only the master's lists are read.
  ros::init(argc, argv, "check_pipeline_launch",
            ros::init_options::AnonymousName | ros::init_options::NoRosout |
                ros::init_options::NoSigintHandler);
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "\n*** pipeline.launch refused: " << e.what() << "\n\n";
    return 1;
  }
}
