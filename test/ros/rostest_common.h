// Shared by the rostest nodes (test/ros/rostest_*.cpp). gtest_main owns main(), so ROS is
// started by a global test environment with the node's real command line (rostest passes
// __name:= and __log:= there), and a background spinner delivers messages while a test waits.
#pragma once

#include <gtest/gtest.h>
#include <ros/ros.h>

#include <fstream>
#include <functional>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

namespace tabletop_shapes_test {

class RosEnvironment : public ::testing::Environment {
 public:
  void SetUp() override {
    std::ifstream file("/proc/self/cmdline", std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(file)),
                           std::istreambuf_iterator<char>());
    size_t start = 0;
    for (size_t end = text.find('\0'); end != std::string::npos;
         start = end + 1, end = text.find('\0', start)) {
      args_.push_back(text.substr(start, end - start));
    }
    std::vector<char*> argv;
    for (std::string& arg : args_) argv.push_back(&arg[0]);
    int argc = static_cast<int>(argv.size());
    ros::init(argc, argv.data(), "tabletop_shapes_rostest");
    spinner_ = std::make_unique<ros::AsyncSpinner>(2);
    spinner_->start();
  }
  void TearDown() override {
    spinner_->stop();
    ros::shutdown();
  }

 private:
  std::vector<std::string> args_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
};

inline ::testing::Environment* const kRosEnvironment =
    ::testing::AddGlobalTestEnvironment(new RosEnvironment);

// Polls `done` every 10 ms until it holds or `seconds` of wall time pass.
inline bool waitFor(const std::function<bool()>& done, double seconds) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    if (done()) return true;
    ros::WallDuration(0.01).sleep();
  }
  return done();
}

}  // namespace tabletop_shapes_test
