// The rostest node of the pipeline tests; each .test file picks its cases with --gtest_filter.
// The chain runs from launch/pipeline.launch in namespace /tabletop_shapes; scenes come from
// bags written at test time by write_scene_bag (test/ros/scene_bag.py), with their ground
// truth on /ground_truth (tabletop_shapes/Objects, same stamp as the cloud).
#include "rostest_common.h"

#include "tabletop_shapes/ros/frame_admission.h"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <dynamic_reconfigure/Reconfigure.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <std_msgs/String.h>
#include <tabletop_shapes/Objects.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_msgs/TFMessage.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cmath>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

namespace {

using tabletop_shapes::Objects;
using tabletop_shapes::ObjectsConstPtr;
using tabletop_shapes_test::waitFor;

const char* const kStages[] = {"preprocess", "table_segmentation", "clustering",
                               "shape_estimation"};

template <typename T = double>
T privateParam(const std::string& name, const T& fallback) {
  return ros::NodeHandle("~").param(name, fallback);
}

size_t objectCount(const Objects& objects) {
  return objects.cubes.size() + objects.cylinders.size() + objects.cones.size() +
         objects.unfitted.size();
}

struct Solid {
  std::string type;
  Eigen::Vector3d center;
  std::array<double, 3> size;  // cube: edges sorted descending; round: r_bottom, r_top, height
};

std::vector<Solid> solids(const Objects& objects) {
  std::vector<Solid> out;
  auto center = [](const geometry_msgs::Pose& pose) {
    return Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  };
  for (const auto& cube : objects.cubes) {
    std::array<double, 3> edges{cube.dimensions.x, cube.dimensions.y, cube.dimensions.z};
    std::sort(edges.begin(), edges.end(), std::greater<double>());
    out.push_back({"cube", center(cube.pose), edges});
  }
  for (const auto& c : objects.cylinders) {
    out.push_back({"cylinder", center(c.pose), {c.radius, c.radius, c.height}});
  }
  for (const auto& c : objects.cones) {
    out.push_back({"cone", center(c.pose), {c.radius_bottom, c.radius_top, c.height}});
  }
  return out;
}

// "cube at (x, y, z); ..." for failure messages.
std::string describe(const Objects& objects) {
  std::ostringstream text;
  text.precision(3);
  for (const Solid& solid : solids(objects)) {
    text << solid.type << " at (" << solid.center.transpose() << "); ";
  }
  for (const auto& unfitted : objects.unfitted) {
    text << "unfitted at (" << unfitted.centroid.x << " " << unfitted.centroid.y << " "
         << unfitted.centroid.z << "): " << unfitted.reason << "; ";
  }
  return text.str();
}

// A stamp in whole microseconds: it survives the PCL header of the later stages unchanged.
ros::Time wholeMicroseconds(const ros::Time& stamp) {
  return ros::Time().fromNSec(stamp.toNSec() / 1000 * 1000);
}

// world -> base_link (a robot's pose in its map) at `stamp`, as one /tf message.
tf2_msgs::TFMessage worldFromBase(const Eigen::Isometry3d& pose, const ros::Time& stamp) {
  geometry_msgs::TransformStamped transform = tf2::eigenToTransform(Eigen::Affine3d(pose.matrix()));
  transform.header.stamp = stamp;
  transform.header.frame_id = "world";
  transform.child_frame_id = "base_link";
  tf2_msgs::TFMessage message;
  message.transforms.push_back(transform);
  return message;
}

// Collects what the pipeline publishes.
class PipelineTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::NodeHandle node;
    objects_sub_ = node.subscribe("/tabletop_shapes/objects", 100, &PipelineTest::onObjects, this);
    truth_sub_ = node.subscribe("/ground_truth", 100, &PipelineTest::onTruth, this);
    markers_sub_ = node.subscribe("/tabletop_shapes/markers", 100, &PipelineTest::onMarkers, this);
    diagnostics_sub_ = node.subscribe("/diagnostics", 100, &PipelineTest::onDiagnostics, this);
    rosout_sub_ = node.subscribe("/rosout", 1000, &PipelineTest::onLog, this);
  }

  void onObjects(const ObjectsConstPtr& msg) {
    const ros::WallTime now = ros::WallTime::now();
    std::lock_guard<std::mutex> lock(mutex_);
    all_answers_.push_back(msg);
    all_answer_wall_times_.push_back(now);
    // Frames refused at Preprocess's admission (a looped bag is faster than the chain) are
    // answered at once; the tests look at the frames the chain worked on.
    if (tabletop_shapes::bridge::isChainBusyReason(msg->reason)) return;
    objects_.push_back(msg);
    objects_wall_times_.push_back(now);
  }
  void onTruth(const ObjectsConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    truth_[msg->header.stamp] = msg;
  }
  void onMarkers(const visualization_msgs::MarkerArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    markers_.push_back(msg);
  }
  void onDiagnostics(const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& status : msg->status) {
      for (const char* stage : kStages) {
        if (status.name == std::string("/tabletop_shapes/") + stage + ": processing") {
          for (const auto& kv : status.values) diagnostics_[stage][kv.key] = kv.value;
          if (status.level == diagnostic_msgs::DiagnosticStatus::WARN) {
            warnings_[stage].push_back(status.message);
          }
        }
      }
    }
  }
  void onScene(const sensor_msgs::PointCloud2ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    latest_scene_ = msg;
  }
  void onLog(const rosgraph_msgs::LogConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    logs_.push_back(msg);
    if (msg->level == rosgraph_msgs::Log::WARN && msg->msg.find("up_frame") != std::string::npos &&
        first_tf_warning_.isZero()) {
      first_tf_warning_ = ros::WallTime::now();
      tf_warning_text_ = msg->msg;
    }
  }

  // How many log lines of at least `level` contain `text`.
  int logsContaining(const std::string& text, uint8_t level) {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<int>(std::count_if(logs_.begin(), logs_.end(), [&](const auto& log) {
      return log->level >= level && log->msg.find(text) != std::string::npos;
    }));
  }

  size_t objectsReceived() {
    std::lock_guard<std::mutex> lock(mutex_);
    return objects_.size();
  }
  ObjectsConstPtr objectsAt(size_t index) {
    std::lock_guard<std::mutex> lock(mutex_);
    return objects_.at(index);
  }
  // The objects message of the frame stamped `stamp` (null while not received).
  ObjectsConstPtr objectsFor(const ros::Time& stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const ObjectsConstPtr& objects : objects_) {
      if (objects->header.stamp == stamp) return objects;
    }
    return nullptr;
  }
  // The reason of any answer (busy ones included) to the frame stamped `stamp`, for messages.
  std::string answerTo(const ros::Time& stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const ObjectsConstPtr& objects : all_answers_) {
      if (objects->header.stamp == stamp) return "\"" + objects->reason + "\"";
    }
    return "none";
  }
  // The ground truth published with the frame stamped `stamp` (null while not received).
  ObjectsConstPtr truthFor(const ros::Time& stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto found = truth_.find(stamp);
    return found == truth_.end() ? ObjectsConstPtr() : found->second;
  }
  // A diagnostic value of a stage as a number (NAN while not reported yet).
  double diagnostic(const std::string& stage, const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto s = diagnostics_.find(stage);
    if (s == diagnostics_.end()) return NAN;
    const auto v = s->second.find(key);
    return v == s->second.end() ? NAN : std::atof(v->second.c_str());
  }

  // Whether a WARN status of `stage` on /diagnostics contained `text`.
  bool warnedOnDiagnostics(const std::string& stage, const std::string& text) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::vector<std::string>& messages = warnings_[stage];
    return std::any_of(messages.begin(), messages.end(), [&](const std::string& message) {
      return message.find(text) != std::string::npos;
    });
  }
  std::string lastWarning(const std::string& stage) {
    std::lock_guard<std::mutex> lock(mutex_);
    return warnings_[stage].empty() ? "(none)" : warnings_[stage].back();
  }

  // For the tests that send the frames themselves: `scene_` is the cloud the fixture bag plays
  // on /scene/points (a topic the chain does not read), `input_` the chain's input topic.
  void startFeed() {
    ros::NodeHandle node;
    // A member, not a local: the looped bag keeps publishing, and a spinner thread may still
    // deliver a cloud while a local subscriber and the variable its callback writes go away.
    scene_sub_ = node.subscribe("/scene/points", 1, &PipelineTest::onScene, this);
    ASSERT_TRUE(waitFor(
        [&] {
          std::lock_guard<std::mutex> lock(mutex_);
          return latest_scene_ != nullptr;
        },
        privateParam("timeout", 40.0)))
        << "no scene on /scene/points";
    {
      std::lock_guard<std::mutex> lock(mutex_);
      scene_ = *latest_scene_;
    }
    input_ = node.advertise<sensor_msgs::PointCloud2>("/camera/depth_registered/points", 100);
    ASSERT_TRUE(waitFor([&] { return input_.getNumSubscribers() > 0; }, 10.0));
  }
  // Sends the scene stamped `stamp` and waits for its objects message: one frame at a time, so
  // that no queue drops it. Null when none came within `seconds`.
  ObjectsConstPtr sendFrame(const ros::Time& stamp, double seconds = 30.0) {
    scene_.header.stamp = stamp;
    input_.publish(scene_);
    ObjectsConstPtr answer;
    waitFor([&] { return (answer = objectsFor(stamp)) != nullptr; }, seconds);
    return answer;
  }
  // A /tf publisher once the manager listens to it (its two listeners, TableSegmentation's
  // and ShapeEstimation's, share one connection).
  ros::Publisher tfPublisher() {
    ros::Publisher tf = ros::NodeHandle().advertise<tf2_msgs::TFMessage>("/tf", 100);
    EXPECT_TRUE(waitFor([&] { return tf.getNumSubscribers() >= 1; }, 10.0))
        << "the manager listens to /tf";
    return tf;
  }
  // The objects of one good frame of the scene: a table and every object.
  void expectObjectsFound(const ObjectsConstPtr& objects) {
    ASSERT_TRUE(objects) << "no objects message";
    EXPECT_TRUE(objects->table_found) << objects->reason;
    EXPECT_EQ(objectCount(*objects), static_cast<size_t>(privateParam("expected_objects", 4)))
        << describe(*objects);
  }

  bool setMinClusterSize(int size) {
    dynamic_reconfigure::Reconfigure call;
    dynamic_reconfigure::IntParameter parameter;
    parameter.name = "min_size";
    parameter.value = size;
    call.request.config.ints.push_back(parameter);
    const std::string service = "/tabletop_shapes/clustering/set_parameters";
    return ros::service::waitForService(service, 10000) && ros::service::call(service, call);
  }

  std::mutex mutex_;
  std::vector<ObjectsConstPtr> objects_;
  std::vector<ros::WallTime> objects_wall_times_;
  // Every objects message, busy answers included, and when each came.
  std::vector<ObjectsConstPtr> all_answers_;
  std::vector<ros::WallTime> all_answer_wall_times_;
  std::map<ros::Time, ObjectsConstPtr> truth_;
  std::vector<visualization_msgs::MarkerArrayConstPtr> markers_;
  std::map<std::string, std::map<std::string, std::string>> diagnostics_;
  std::map<std::string, std::vector<std::string>> warnings_;  // WARN messages by stage
  ros::WallTime first_tf_warning_;
  std::string tf_warning_text_;
  std::vector<rosgraph_msgs::LogConstPtr> logs_;
  sensor_msgs::PointCloud2 scene_;
  ros::Publisher input_;
  sensor_msgs::PointCloud2ConstPtr latest_scene_;  // the bag's cloud on /scene/points
  // Declared last, so destroyed first: no callback runs into members already gone.
  ros::Subscriber objects_sub_, truth_sub_, markers_sub_, diagnostics_sub_, rosout_sub_, scene_sub_;
};

// Rendered scenes: every object found with the right type and dimensions, frame after frame.
TEST_F(PipelineTest, BagReplayObjectsMatchGroundTruth) {
  const int min_frames = static_cast<int>(privateParam("min_frames", 3));
  const double edge_tolerance = privateParam("edge_tolerance", 0.10);       // relative
  const double radius_tolerance = privateParam("radius_tolerance", 0.005);  // m
  const double height_tolerance = privateParam("height_tolerance", 0.015);  // m
  const double timeout = privateParam("timeout", 40.0);

  int evaluated = 0;
  size_t next = 0;
  waitFor(
      [&]() -> bool {
        while (next < objectsReceived() && evaluated < min_frames) {
          const ObjectsConstPtr result = objectsAt(next++);
          const ObjectsConstPtr truth = truthFor(result->header.stamp);
          if (!truth) {
            ADD_FAILURE() << "no ground truth with the stamp of objects " << result->header.stamp;
            continue;
          }
          ++evaluated;
          SCOPED_TRACE("frame stamped " + std::to_string(result->header.stamp.toSec()));
          EXPECT_TRUE(result->table_found);
          EXPECT_EQ(result->header.frame_id, truth->header.frame_id);
          const std::vector<Solid> expected = solids(*truth), found = solids(*result);
          EXPECT_EQ(objectCount(*result), expected.size()) << "found: " << describe(*result);
          for (const Solid& want : expected) {
            const auto nearest =
                std::min_element(found.begin(), found.end(), [&](const Solid& a, const Solid& b) {
                  return (a.center - want.center).norm() < (b.center - want.center).norm();
                });
            if (nearest == found.end()) {
              ADD_FAILURE() << "no " << want.type << " found";
              continue;
            }
            const Solid& got = *nearest;
            SCOPED_TRACE(want.type + " at " + std::to_string(want.center.x()) + ", " +
                         std::to_string(want.center.y()) + ", " + std::to_string(want.center.z()));
            EXPECT_LT((got.center - want.center).norm(), 0.03) << "centre";
            EXPECT_EQ(got.type, want.type);
            std::printf(
                "%s: found %s, size %.4f %.4f %.4f, truth %.4f %.4f %.4f, centre off %.4f m\n",
                want.type.c_str(), got.type.c_str(), got.size[0], got.size[1], got.size[2],
                want.size[0], want.size[1], want.size[2], (got.center - want.center).norm());
            if (got.type != want.type) continue;
            if (want.type == "cube") {
              for (int i = 0; i < 3; ++i) {
                EXPECT_NEAR(got.size[i], want.size[i], edge_tolerance * want.size[i])
                    << "edge " << i;
              }
            } else {
              EXPECT_NEAR(got.size[0], want.size[0], radius_tolerance) << "bottom radius";
              EXPECT_NEAR(got.size[1], want.size[1], radius_tolerance) << "top radius";
              EXPECT_NEAR(got.size[2], want.size[2], height_tolerance) << "height";
            }
          }
        }
        return evaluated >= min_frames;
      },
      timeout);
  EXPECT_GE(evaluated, min_frames) << "frames evaluated before the timeout";
}

// The checks of BorderBoxIsTruncated on one frame.
void checkBorderBoxFrame(const Objects& result, const Objects& truth) {
  ASSERT_TRUE(result.table_found) << result.reason;
  const Eigen::Vector3d up(result.table.coefficients[0], result.table.coefficients[1],
                           result.table.coefficients[2]);
  int cut_boxes = 0;
  for (const auto& want : truth.cubes) {
    if (!want.truncated) continue;
    ++cut_boxes;
    const Eigen::Vector3d centre(want.pose.position.x, want.pose.position.y, want.pose.position.z);
    ASSERT_GT(centre.x(), 0.0) << "the scene's border box lies on the right border";
    const tabletop_shapes::Cube* got = nullptr;
    for (const auto& cube : result.cubes) {
      const Eigen::Vector3d c(cube.pose.position.x, cube.pose.position.y, cube.pose.position.z);
      if ((c - centre).norm() < 0.10) got = &cube;
    }
    ASSERT_NE(got, nullptr) << "no box within 10 cm of the cut box; found: " << describe(result);
    EXPECT_TRUE(got->truncated);
    const auto& q = got->pose.orientation;
    const Eigen::Matrix3d axes =
        Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
    int across_border = 0, vertical = 0;  // the box axes nearest camera x and up
    for (int i = 1; i < 3; ++i) {
      if (std::abs(axes.col(i).x()) > std::abs(axes.col(across_border).x())) {
        across_border = i;
      }
      if (std::abs(axes.col(i).dot(up)) > std::abs(axes.col(vertical).dot(up))) {
        vertical = i;
      }
    }
    ASSERT_NE(across_border, vertical);
    EXPECT_TRUE(got->dimensions_lower_bound[across_border])
        << "the edge along the image's x (axis " << across_border << ")";
    EXPECT_FALSE(got->dimensions_lower_bound[vertical])
        << "the height (axis " << vertical << ") is seen whole";
  }
  EXPECT_EQ(cut_boxes, 1) << "the scene has one box cut by the border";
  for (const auto& cube : result.cubes) {
    if (!cube.truncated) continue;
    const Eigen::Vector3d c(cube.pose.position.x, cube.pose.position.y, cube.pose.position.z);
    EXPECT_GT(c.x() / c.z(), 0.3) << "only the box on the right border is cut";
  }
  for (const auto& cylinder : result.cylinders) EXPECT_FALSE(cylinder.truncated);
  for (const auto& cone : result.cones) EXPECT_FALSE(cone.truncated);
}

// A box cut by the image's right border (everyday scene, seed 2: the border box's centre lies
// on that border) comes out of the chain `truncated`, its edge across the border a lower bound
// and its height not; the objects wholly in view are not truncated. The view travels from
// Preprocess (organised cloud) to ShapeEstimation on the `view` topic.
TEST_F(PipelineTest, BorderBoxIsTruncated) {
  const int min_frames = static_cast<int>(privateParam("min_frames", 2));
  int evaluated = 0;
  size_t next = 0;
  waitFor(
      [&]() -> bool {
        while (next < objectsReceived() && evaluated < min_frames) {
          const ObjectsConstPtr result = objectsAt(next++);
          const ObjectsConstPtr truth = truthFor(result->header.stamp);
          if (!truth) continue;
          ++evaluated;
          SCOPED_TRACE("frame stamped " + std::to_string(result->header.stamp.toSec()));
          checkBorderBoxFrame(*result, *truth);
        }
        return evaluated >= min_frames;
      },
      privateParam("timeout", 40.0));
  EXPECT_GE(evaluated, min_frames) << "frames evaluated before the timeout";
}

// Inside one manager every cloud a stage receives is the very object the previous stage
// published; standalone (expect_zero_copy false) every one was serialised and copied: the
// positive control that shows the check can tell the two apart.
TEST_F(PipelineTest, BagReplayCloudsSharedNotCopied) {
  const bool expect_zero_copy = ros::NodeHandle("~").param("expect_zero_copy", true);
  const char* key_shared = "input clouds shared (zero-copy)";
  const char* key_copied = "input clouds copied";
  const bool reported = waitFor(
      [&] {
        for (const char* stage : {"table_segmentation", "clustering", "shape_estimation"}) {
          if (!(diagnostic(stage, key_shared) + diagnostic(stage, key_copied) >= 2)) return false;
        }
        return true;
      },
      privateParam("timeout", 40.0));
  ASSERT_TRUE(reported) << "the stages did not report two input clouds each";
  for (const char* stage : {"table_segmentation", "clustering", "shape_estimation"}) {
    SCOPED_TRACE(stage);
    if (expect_zero_copy) {
      EXPECT_GE(diagnostic(stage, key_shared), 2);
      EXPECT_EQ(diagnostic(stage, key_copied), 0);
    } else {
      EXPECT_EQ(diagnostic(stage, key_shared), 0);
      EXPECT_GE(diagnostic(stage, key_copied), 2);
    }
  }
}

// Markers: a solid and a label per object, the table hull as a closed line strip; every
// stage reports its processing time.
TEST_F(PipelineTest, BagReplayMarkersAndTimings) {
  ASSERT_TRUE(waitFor([&] { return objectsReceived() >= 1; }, privateParam("timeout", 40.0)));
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mutex_);
        return !markers_.empty();
      },
      5.0));
  const ObjectsConstPtr objects = objectsAt(0);
  visualization_msgs::MarkerArrayConstPtr markers;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    markers = markers_.front();
  }
  size_t solids = 0, labels = 0, strips = 0;
  for (const auto& m : markers->markers) {
    if (m.action != visualization_msgs::Marker::ADD) continue;
    if (m.ns == "solids") {
      ++solids;
      EXPECT_GT(m.color.a, 0.1);
      EXPECT_LT(m.color.a, 1.0) << "translucent";
    }
    if (m.ns == "labels") {
      ++labels;
      EXPECT_NE(m.text.find(" cm"), std::string::npos) << m.text;
    }
    if (m.ns == "table" && m.type == visualization_msgs::Marker::LINE_STRIP) {
      ++strips;
      ASSERT_GE(m.points.size(), 4u);
      EXPECT_EQ(m.points.front().x, m.points.back().x) << "closed outline";
    }
  }
  EXPECT_EQ(solids, objectCount(*objects));
  EXPECT_EQ(labels, objectCount(*objects));
  EXPECT_EQ(strips, 1u);
  ASSERT_TRUE(waitFor(
      [&] {
        for (const char* stage : kStages) {
          if (!(diagnostic(stage, "frames") >= 1)) return false;
        }
        return true;
      },
      10.0))
      << "every stage reports on /diagnostics";
  for (const char* stage : kStages) {
    EXPECT_GT(diagnostic(stage, "last frame [ms]"), 0.0) << stage;
  }
}

// Boxes a real scene's labelled points give (~expected_boxes: "edges sorted descending and the
// centre's height above the table [m]" per box, boxes apart by ';'). Each must be matched by
// one cube of `objects`, every number within `tolerance`.
void expectBoxes(const Objects& objects, const std::string& expected_boxes, double tolerance) {
  const Eigen::Vector3d normal(objects.table.coefficients[0], objects.table.coefficients[1],
                               objects.table.coefficients[2]);
  const double d = objects.table.coefficients[3];
  std::vector<Solid> cubes;
  for (const Solid& solid : solids(objects)) {
    if (solid.type == "cube") cubes.push_back(solid);
  }
  std::istringstream boxes(expected_boxes);
  std::string box;
  while (std::getline(boxes, box, ';')) {
    std::istringstream numbers(box);
    std::array<double, 4> want{};  // edges, height of the centre
    for (double& number : want) ASSERT_TRUE(numbers >> number) << "bad ~expected_boxes: " << box;
    auto off = [&](const Solid& cube) {
      double worst = std::abs(normal.dot(cube.center) + d - want[3]);
      for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(cube.size[k] - want[k]));
      return worst;
    };
    const auto nearest =
        std::min_element(cubes.begin(), cubes.end(),
                         [&](const Solid& a, const Solid& b) { return off(a) < off(b); });
    ASSERT_NE(nearest, cubes.end()) << "no cube for " << box << "; " << describe(objects);
    EXPECT_LE(off(*nearest), tolerance)
        << "box " << box << ": nearest cube " << nearest->size[0] << " x " << nearest->size[1]
        << " x " << nearest->size[2] << ", centre " << normal.dot(nearest->center) + d
        << " m above the table";
    cubes.erase(nearest);
  }
}

// A real OSD scene: the expected number of objects comes out of every frame, and with
// ~expected_boxes the boxes' sizes and heights (each on the table or on the box under it).
TEST_F(PipelineTest, RealSceneExpectedObjectCount) {
  const int expected = static_cast<int>(privateParam("expected_objects", -1));
  ASSERT_GE(expected, 0) << "set ~expected_objects";
  const std::string expected_boxes = privateParam<std::string>("expected_boxes", "");
  ASSERT_TRUE(waitFor([&] { return objectsReceived() >= 2; }, privateParam("timeout", 40.0)));
  for (size_t i = 0; i < 2; ++i) {
    const ObjectsConstPtr objects = objectsAt(i);
    EXPECT_TRUE(objects->table_found);
    EXPECT_EQ(objectCount(*objects), static_cast<size_t>(expected)) << describe(*objects);
    if (!expected_boxes.empty())
      expectBoxes(*objects, expected_boxes, privateParam("box_tolerance", 0.01));
  }
}

// dynamic_reconfigure: a minimum cluster size above every object's size empties `objects`
// from the next frame on; lowering it brings them back.
TEST_F(PipelineTest, ReconfigureMinClusterSize) {
  const double timeout = privateParam("timeout", 40.0);
  ASSERT_TRUE(waitFor([&] { return objectsReceived() >= 1; }, timeout));
  const size_t before = objectCount(*objectsAt(objectsReceived() - 1));
  ASSERT_GT(before, 0u) << "the scene must have objects to start with";

  // Frames already past the clustering stage (queued in the synchronisers) still arrive with
  // the old setting: wait for the first frame with the new one, then every later frame must
  // keep it.
  auto expectSettingHolds = [&](size_t count, const char* what) {
    size_t first = objectsReceived();
    ASSERT_TRUE(waitFor(
        [&] {
          while (first < objectsReceived() && objectCount(*objectsAt(first)) != count) ++first;
          return first < objectsReceived();
        },
        timeout))
        << "no frame with " << count << " objects after " << what;
    ASSERT_TRUE(waitFor([&] { return objectsReceived() >= first + 4; }, timeout));
    for (size_t i = first; i < first + 4; ++i) {
      EXPECT_EQ(objectCount(*objectsAt(i)), count) << "message " << i - first << " after " << what;
      EXPECT_TRUE(objectsAt(i)->table_found) << "the table is still there";
    }
  };
  // At most max_size (200000): a larger min_size contradicts it and is refused.
  ASSERT_TRUE(setMinClusterSize(200000));
  expectSettingHolds(0, "min_size 200000");
  ASSERT_TRUE(setMinClusterSize(100));
  expectSettingHolds(before, "min_size 100");
}

// up_frame without a transform: throttled warnings, frames skipped, no crash, and for every
// skipped frame an objects message with the reason (issue 13/16: a consumer can tell "no
// transform" from "stalled"); once the transform appears (published late by the fixture) the
// objects come.
TEST_F(PipelineTest, MissingUpTransformWarnsThenRecovers) {
  const double timeout = privateParam("timeout", 40.0);
  ASSERT_TRUE(
      waitFor([&] { return diagnostic("table_segmentation", "frames skipped") >= 1; }, timeout))
      << "frames without a transform are reported as skipped";
  ASSERT_TRUE(waitFor([&] { return objectsReceived() >= 1; }, 5.0))
      << "an objects message for the skipped frame";
  const ObjectsConstPtr skipped = objectsAt(0);
  EXPECT_FALSE(skipped->table_found);
  EXPECT_EQ(objectCount(*skipped), 0u);
  EXPECT_NE(skipped->reason.find("no transform from up_frame 'base_link'"), std::string::npos)
      << skipped->reason;
  EXPECT_EQ(skipped->header.frame_id, "camera_rgb_optical_frame");
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mutex_);
        return !first_tf_warning_.isZero();
      },
      10.0))
      << "a warning naming up_frame on /rosout";
  size_t first_result = 0;
  ASSERT_TRUE(waitFor(
      [&] {
        while (first_result < objectsReceived() && !objectsAt(first_result)->reason.empty()) {
          ++first_result;
        }
        return first_result < objectsReceived();
      },
      timeout))
      << "objects once the transform is there";
  {
    std::lock_guard<std::mutex> lock(mutex_);
    EXPECT_GT(objects_wall_times_[first_result], first_tf_warning_);
    EXPECT_NE(tf_warning_text_.find("base_link"), std::string::npos) << tf_warning_text_;
  }
  EXPECT_TRUE(objectsAt(first_result)->table_found);
  EXPECT_EQ(objectCount(*objectsAt(first_result)),
            static_cast<size_t>(privateParam("expected_objects", 4)));
  // Every frame skipped before got its message: one per skipped frame at the table stage.
  EXPECT_GE(static_cast<double>(first_result),
            diagnostic("table_segmentation", "frames skipped") - 1);
}

// Clouds a robot can send by mistake, each with what the pipeline must say about it.
struct BadCloud {
  std::string what;
  sensor_msgs::PointCloud2 cloud;
  std::vector<std::string> messages;  // each expected in a log line of a stage
  uint8_t level;
  std::string objects_reason;  // expected in the reason of the frame's objects message
};

sensor_msgs::PointCloud2 xyzCloud(uint32_t width, uint32_t height,
                                  const std::function<Eigen::Vector3f(uint32_t)>& point) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header.frame_id = "camera_rgb_optical_frame";
  cloud.header.stamp = ros::Time::now();
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  modifier.setPointCloud2FieldsByString(1, "xyz");
  modifier.resize(width * height);
  cloud.width = width;
  cloud.height = height;
  cloud.row_step = width * cloud.point_step;
  cloud.is_dense = false;
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
  for (uint32_t i = 0; i < width * height; ++i, ++x, ++y, ++z) {
    const Eigen::Vector3f p = point(i);
    *x = p.x();
    *y = p.y();
    *z = p.z();
  }
  return cloud;
}

std::vector<BadCloud> badClouds() {
  const auto scatter = [](uint32_t i) {  // a 1 m cube of points: no plane anywhere
    return Eigen::Vector3f(std::fmod(i * 0.6180339f, 1.0f) - 0.5f,
                           std::fmod(i * 0.7548776f, 1.0f) - 0.5f,
                           1.0f + std::fmod(i * 0.5698403f, 1.0f));
  };
  using Log = rosgraph_msgs::Log;
  std::vector<BadCloud> clouds;
  sensor_msgs::PointCloud2 no_z = xyzCloud(40, 30, scatter);
  no_z.fields.pop_back();
  clouds.push_back({"no z field",
                    no_z,
                    {"skipping input cloud: no field 'z'"},
                    Log::ERROR,
                    "invalid cloud: no field 'z'"});
  sensor_msgs::PointCloud2 double_x = xyzCloud(40, 30, scatter);
  double_x.fields[0].datatype = sensor_msgs::PointField::FLOAT64;
  clouds.push_back({"x as float64",
                    double_x,
                    {"skipping input cloud: field 'x' is not FLOAT32"},
                    Log::ERROR,
                    "invalid cloud: field 'x' is not FLOAT32"});
  sensor_msgs::PointCloud2 truncated = xyzCloud(40, 30, scatter);
  truncated.data.resize(truncated.data.size() / 2);
  clouds.push_back({"data cut in half",
                    truncated,
                    {"skipping input cloud: data shorter"},
                    Log::ERROR,
                    "invalid cloud: data shorter than declared"});
  // issue 16, finding 3: 108 bytes that stalled the chain for 5-12 s
  sensor_msgs::PointCloud2 endless_rows = xyzCloud(0, 1, scatter);
  endless_rows.height = 0xffffffffu;
  endless_rows.row_step = 0;
  clouds.push_back({"width 0, height 2^32-1",
                    endless_rows,
                    {"skipping input cloud: width 0 x height 4294967295"},
                    Log::ERROR,
                    "invalid cloud: width 0 x height 4294967295"});
  // finding 4: 100 x 100 declared, 4.9 MB carried
  sensor_msgs::PointCloud2 longer = xyzCloud(100, 100, scatter);
  longer.data.resize(4900000);
  clouds.push_back({"data longer than declared",
                    longer,
                    {"skipping input cloud: data longer than declared: 4900000 bytes"},
                    Log::ERROR,
                    "invalid cloud: data longer"});
  sensor_msgs::PointCloud2 short_rows = xyzCloud(40, 30, scatter);
  short_rows.row_step = 17;
  clouds.push_back({"row_step shorter than a row",
                    short_rows,
                    {"skipping input cloud: row_step 17 is shorter than width 40"},
                    Log::ERROR,
                    "invalid cloud: row_step 17"});
  sensor_msgs::PointCloud2 no_frame = xyzCloud(40, 30, scatter);
  no_frame.header.frame_id = "";
  clouds.push_back({"empty frame_id",
                    no_frame,
                    {"no transform from up_frame 'base_link' to ''"},
                    Log::WARN,
                    "no transform from up_frame 'base_link' to ''"});
  clouds.push_back({"empty",
                    xyzCloud(0, 1, scatter),
                    {"input cloud is empty", "no table in the frame: empty cloud"},
                    Log::WARN,
                    "no table: empty cloud"});
  clouds.push_back({"all NaN",
                    xyzCloud(64, 48, [](uint32_t) { return Eigen::Vector3f::Constant(NAN); }),
                    {"none of the 3072 input points is finite"},
                    Log::WARN,
                    "no table: empty cloud"});
  clouds.push_back({"no table",
                    xyzCloud(100, 100, scatter),
                    {"no table in the frame: no plane"},
                    Log::WARN,
                    "no table: no plane"});
  // 5 million points: refused from the sizes, the next frame on time (below)
  clouds.push_back({"5 million points",
                    xyzCloud(2500, 2000, scatter),
                    {"skipping input cloud: 5000000 points (2500 x 2000) is above max_points"},
                    Log::ERROR,
                    "invalid cloud: 5000000 points"});
  return clouds;
}

// Bad input between good frames: every bad cloud gets its clear message (at once, even right
// after a different problem) and a count in /diagnostics, a repeated problem is throttled,
// nothing crashes, and the good frames after them still give the objects.
// output_frame without a transform: every frame is skipped by ShapeEstimation, counted in its
// diagnostics, logged once per 5 s (tf's text holds times, so the throttle keys on frames), and
// answered by an objects message with the reason, in the cloud's frame.
TEST_F(PipelineTest, MissingOutputTransformIsReportedAndThrottled) {
  const double timeout = privateParam("timeout", 40.0);
  ASSERT_TRUE(
      waitFor([&] { return diagnostic("shape_estimation", "frames skipped") >= 1; }, timeout))
      << "frames without the output transform are reported as skipped";
  const std::string text = "no transform to output_frame 'map'";
  const double skipped_before = diagnostic("shape_estimation", "frames skipped");
  // Counted from here: a slow start-up (a loaded machine) logs more lines before it.
  const int warnings_before = logsContaining(text, rosgraph_msgs::Log::WARN);
  const ros::WallTime start = ros::WallTime::now();
  ASSERT_TRUE(waitFor(
      [&] { return diagnostic("shape_estimation", "frames skipped") >= skipped_before + 6; },
      timeout));
  const double seconds = (ros::WallTime::now() - start).toSec();
  EXPECT_GE(logsContaining(text, rosgraph_msgs::Log::WARN), 1) << "a warning naming the frame";
  EXPECT_LE(logsContaining(text, rosgraph_msgs::Log::WARN) - warnings_before,
            1 + static_cast<int>(seconds / 5.0))
      << "throttled to one line per 5 s";
  ASSERT_GE(objectsReceived(), 6u) << "an objects message per skipped frame";
  for (size_t i = 0; i < objectsReceived(); ++i) {
    const ObjectsConstPtr objects = objectsAt(i);
    EXPECT_EQ(objectCount(*objects), 0u) << "nothing found in a frame that is not output_frame";
    EXPECT_FALSE(objects->table_found);
    EXPECT_NE(objects->reason.find(text), std::string::npos) << objects->reason;
    EXPECT_NE(objects->header.frame_id, "map");
  }
}

TEST_F(PipelineTest, BadInputIsReportedAndThePipelineKeepsRunning) {
  const double timeout = privateParam("timeout", 40.0);
  // The RSS baseline is the warm chain's: after a few frames (the fits' worker threads and their
  // malloc arenas exist by then) and a diagnostics period (1 s) later.
  ASSERT_TRUE(waitFor([&] { return objectsReceived() >= 3; }, timeout)) << "no objects at all";
  ros::WallDuration(1.5).sleep();
  ASSERT_TRUE(waitFor([&] { return diagnostic("preprocess", "process RSS [MB]") > 0; }, 5.0));
  const double rss_before = diagnostic("preprocess", "process RSS [MB]");
  ros::NodeHandle node;
  ros::Publisher input =
      node.advertise<sensor_msgs::PointCloud2>("/camera/depth_registered/points", 10);
  ASSERT_TRUE(waitFor([&] { return input.getNumSubscribers() > 0; }, 10.0));
  // Each bad cloud is sent every 0.5 s until its message appears: the stages keep only the
  // newest frame (queue_size 1), so under load a single one may be replaced by a good frame.
  const std::vector<BadCloud> clouds = badClouds();
  for (BadCloud cloud : clouds) {
    SCOPED_TRACE(cloud.what);
    ros::WallTime next_send;
    std::set<ros::Time> sent_stamps;
    const size_t objects_before = objectsReceived();
    auto answered = [&] {  // an objects message with the stamp of a sent cloud and the reason
      for (size_t i = objects_before; i < objectsReceived(); ++i) {
        const ObjectsConstPtr objects = objectsAt(i);
        if (sent_stamps.count(objects->header.stamp) &&
            objects->reason.find(cloud.objects_reason) != std::string::npos) {
          EXPECT_EQ(objectCount(*objects), 0u);
          EXPECT_FALSE(objects->table_found);
          return true;
        }
      }
      return false;
    };
    const ros::WallTime start = ros::WallTime::now();
    EXPECT_TRUE(waitFor(
        [&] {
          if (ros::WallTime::now() >= next_send) {
            cloud.cloud.header.stamp = wholeMicroseconds(ros::Time::now());
            sent_stamps.insert(cloud.cloud.header.stamp);
            input.publish(cloud.cloud);
            next_send = ros::WallTime::now() + ros::WallDuration(0.5);
          }
          return answered() && std::all_of(cloud.messages.begin(), cloud.messages.end(),
                                           [&](const std::string& message) {
                                             return logsContaining(message, cloud.level);
                                           });
        },
        15.0))
        << "log lines containing \"" << cloud.messages.front()
        << "\" (and the others) and an objects message with reason \"" << cloud.objects_reason
        << "\"";
    std::printf("%-30s answered in %.2f s\n", cloud.what.c_str(),
                (ros::WallTime::now() - start).toSec());
    // The next good frame on time: a looped 2 Hz scene gives one within ~2 s of the answer.
    const size_t received = objectsReceived();
    const ros::WallTime answered_at = ros::WallTime::now();
    EXPECT_TRUE(waitFor(
        [&] {
          for (size_t i = received; i < objectsReceived(); ++i) {
            if (objectsAt(i)->table_found) return true;
          }
          return false;
        },
        10.0))
        << "a good frame after the bad one";
    EXPECT_LT((ros::WallTime::now() - answered_at).toSec(), 5.0) << "the next frame on time";
  }
  EXPECT_TRUE(waitFor([&] { return diagnostic("preprocess", "frames skipped") >= 7; }, 5.0))
      << "the 7 unreadable clouds are counted as skipped by preprocess";
  // Memory (finding 5): the 5-million-point frame leaves nothing behind. Under load a stage may
  // still hold a large frame when the last answer arrives, so RSS gets a few diagnostics periods
  // to come back (the finding was 490-600 MB kept through 20 further frames).
  double rss_after = 0.0;
  waitFor(
      [&] {
        rss_after = diagnostic("preprocess", "process RSS [MB]");
        return rss_after > 10.0 && rss_after < rss_before + 60.0;
      },
      10.0);
  EXPECT_GT(rss_after, 10.0);
  EXPECT_LT(rss_after, rss_before + 60.0) << "manager RSS before the bad input " << rss_before;
  EXPECT_TRUE(
      waitFor([&] { return diagnostic("table_segmentation", "frames without result") >= 2; }, 5.0))
      << "the empty and the table-less clouds are counted as frames without a table";
  EXPECT_TRUE(waitFor([&] { return diagnostic("preprocess", "frames without result") >= 2; }, 5.0))
      << "the empty and the all-NaN clouds are counted as frames without points by preprocess";
  // Throttled: a problem repeated at 10 Hz is logged once, not 20 times.
  const int before = logsContaining("no field 'z'", rosgraph_msgs::Log::ERROR);
  for (int i = 0; i < 20; ++i) {
    input.publish(clouds[0].cloud);
    ros::WallDuration(0.1).sleep();
  }
  ros::WallDuration(1.0).sleep();
  EXPECT_LE(logsContaining("no field 'z'", rosgraph_msgs::Log::ERROR) - before, 1);
  // And the good frames still come through.
  const size_t received = objectsReceived();
  ASSERT_TRUE(waitFor([&] { return objectsReceived() >= received + 2; }, timeout))
      << "objects after the bad input";
  const ObjectsConstPtr last = objectsAt(objectsReceived() - 1);
  EXPECT_EQ(last->reason, "");
  EXPECT_EQ(objectCount(*last), static_cast<size_t>(privateParam("expected_objects", 4)));
}

// Finding 6 and 7: 1800 frames in, 228 objects out, and no count of the rest anywhere. Now
// Preprocess admits a frame only while fewer than ~max_frames_in_flight are in the chain and
// answers the others at once ("skipped: chain busy ..."), so that at 30 Hz every frame sent is
// answered on `objects`, except the ones dropped at Preprocess's own input queue, which are
// counted there (gaps in the frame numbers). The frames the chain works on do not wait behind
// a backlog: their latency stays close to a frame's sent alone.
TEST_F(PipelineTest, EveryFrameIsAnsweredOrCountedAsDropped) {
  ASSERT_NO_FATAL_FAILURE(startFeed());
  ros::Publisher& input = input_;
  sensor_msgs::PointCloud2 cloud = scene_;
  auto latencyOf = [&](const ros::Time& stamp) -> double {
    std::lock_guard<std::mutex> lock(mutex_);
    for (size_t i = 0; i < objects_.size(); ++i) {
      if (objects_[i]->header.stamp == stamp) {
        return (objects_wall_times_[i].toSec() - stamp.toSec()) * 1e3;
      }
    }
    return NAN;
  };
  // Frames sent alone (each after the last one's answer), numbered from 1 as a driver does:
  // a frame lost before preprocess received its first one is no gap it can see. The first
  // ones warm the chain up; the last few give a frame's latency with nothing else in flight.
  std::vector<double> alone_ms;
  uint32_t seq = 0;
  for (int i = 0; i < 8; ++i) {
    cloud.header.seq = ++seq;
    const ros::Time stamp = wholeMicroseconds(ros::Time::now());
    scene_ = cloud;
    ASSERT_TRUE(sendFrame(stamp, 30.0))
        << "frame " << seq << " sent alone got no result; its answer: " << answerTo(stamp);
    if (i >= 3) alone_ms.push_back(latencyOf(stamp));
  }
  std::sort(alone_ms.begin(), alone_ms.end());
  const double alone_median_ms = alone_ms[alone_ms.size() / 2];
  ros::WallDuration(2.2).sleep();  // their counts on /diagnostics
  auto preprocess_in = [&] {
    return diagnostic("preprocess", "frames") + diagnostic("preprocess", "frames skipped") +
           diagnostic("preprocess", "frames skipped: chain busy") +
           diagnostic("preprocess", "frames dropped at input queue");
  };
  const double in_before = preprocess_in();
  const double dropped_before = diagnostic("preprocess", "frames dropped at input queue");
  const double busy_before = diagnostic("preprocess", "frames skipped: chain busy");
  std::map<std::string, double> dropped_later_before;
  for (const char* stage : {"table_segmentation", "clustering", "shape_estimation"}) {
    dropped_later_before[stage] = diagnostic(stage, "frames dropped at input queue");
  }
  const int sent = 150;  // 5 s at 30 Hz
  std::vector<ros::Time> stamps;
  ros::WallRate rate(30.0);
  for (int i = 0; i < sent; ++i) {
    cloud.header.seq = ++seq;
    cloud.header.stamp = wholeMicroseconds(ros::Time::now());
    stamps.push_back(cloud.header.stamp);
    input.publish(cloud);
    rate.sleep();
  }
  // Quiet: wait until the counts stop moving (two diagnostics periods alike).
  auto totals = [&] {
    std::vector<double> values{static_cast<double>(objectsReceived())};
    for (const char* stage : kStages) {
      for (const char* key : {"frames", "frames skipped", "frames skipped: chain busy",
                              "frames dropped at input queue"}) {
        values.push_back(diagnostic(stage, key));
      }
    }
    return values;
  };
  std::vector<double> last = totals();
  ASSERT_TRUE(waitFor(
      [&] {
        ros::WallDuration(2.2).sleep();
        const std::vector<double> now = totals();
        const bool settled = now == last;
        last = now;
        return settled;
      },
      30.0));
  const double in = preprocess_in() - in_before;
  const double dropped_at_preprocess =
      diagnostic("preprocess", "frames dropped at input queue") - dropped_before;
  const double busy = diagnostic("preprocess", "frames skipped: chain busy") - busy_before;
  EXPECT_EQ(in, sent) << "frames in at preprocess: processed + skipped + busy + dropped";

  // Every frame's answers: each stamp answered at most once, with a result (a table and the
  // objects) or as busy.
  size_t answered = 0, with_result = 0, answered_busy = 0;
  std::vector<double> result_ms, busy_ms;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    std::map<ros::Time, int> answers;
    for (size_t i = 0; i < all_answers_.size(); ++i) {
      const Objects& objects = *all_answers_[i];
      const double latency_ms =
          (all_answer_wall_times_[i].toSec() - objects.header.stamp.toSec()) * 1e3;
      if (std::find(stamps.begin(), stamps.end(), objects.header.stamp) == stamps.end()) continue;
      ++answers[objects.header.stamp];
      ++answered;
      if (objects.reason.empty()) {
        ++with_result;
        EXPECT_TRUE(objects.table_found);
        EXPECT_EQ(objectCount(objects), static_cast<size_t>(privateParam("expected_objects", 4)))
            << describe(objects);
        result_ms.push_back(latency_ms);
      } else {
        EXPECT_EQ(objects.reason.rfind("skipped: chain busy (", 0), 0u) << objects.reason;
        EXPECT_FALSE(objects.table_found);
        ++answered_busy;
        busy_ms.push_back(latency_ms);
      }
    }
    for (const auto& [stamp, count] : answers) EXPECT_EQ(count, 1) << "stamp " << stamp;
  }
  double dropped_later = 0;
  for (const char* stage : {"table_segmentation", "clustering", "shape_estimation"}) {
    dropped_later +=
        diagnostic(stage, "frames dropped at input queue") - dropped_later_before[stage];
  }
  std::printf(
      "30 Hz, %d frames: in %.0f, dropped at preprocess %.0f, busy %.0f; answered %zu "
      "(result %zu, busy %zu); dropped later %.0f\n",
      sent, in, dropped_at_preprocess, busy, answered, with_result, answered_busy, dropped_later);
  EXPECT_EQ(static_cast<double>(answered), in - dropped_at_preprocess)
      << "every frame taken in at preprocess is answered";
  EXPECT_EQ(static_cast<double>(answered_busy), busy) << "/diagnostics counts the busy answers";
  EXPECT_EQ(dropped_later, 0) << "admission keeps later queues from dropping frames";
  EXPECT_GT(answered_busy, 0u) << "30 Hz is faster than the chain: some frames must be busy";
  EXPECT_GE(with_result, 5u);
  ASSERT_FALSE(result_ms.empty());
  std::sort(result_ms.begin(), result_ms.end());
  const double median_ms = result_ms[result_ms.size() / 2];
  std::sort(busy_ms.begin(), busy_ms.end());
  const double busy_median_ms = busy_ms.empty() ? NAN : busy_ms[busy_ms.size() / 2];
  std::printf(
      "latency: alone median %.0f ms; at 30 Hz median %.0f ms, max %.0f ms; busy "
      "answers median %.0f ms, max %.0f ms\n",
      alone_median_ms, median_ms, result_ms.back(), busy_median_ms,
      busy_ms.empty() ? NAN : busy_ms.back());
  // No backlog: a frame's latency is its trip to Preprocess under the 30 Hz flow of 10 MB
  // clouds (the busy answers' own latency, set by the machine's load) plus about one frame's
  // work (sent alone, measured minutes before at another load: hence 3x) and a frame period
  // of waiting. Without admission the answered frames waited behind others at every queue:
  // p50 324-849 ms against ~115-137 ms alone in the soaks.
  ASSERT_FALSE(busy_ms.empty());
  EXPECT_LE(median_ms, busy_median_ms + 3.0 * alone_median_ms + 100.0);
}

// TF jumping (issue 16): world -> base_link, a robot's pose, jumps 3 m and 90 deg about up
// between frames. Each frame's objects, given in world (up_frame and output_frame are world),
// must lie where the pose of its own stamp puts them: taken back to base_link they are the
// same in every frame. The newest transform, or one between two frames, puts them metres off.
TEST_F(PipelineTest, EachFrameUsesTheTransformOfItsOwnStamp) {
  ASSERT_NO_FATAL_FAILURE(startFeed());
  ros::Publisher tf = tfPublisher();
  const Eigen::Isometry3d poses[2] = {
      Eigen::Isometry3d::Identity(),
      Eigen::Translation3d(3.0, -2.0, 0.0) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())};
  std::vector<Eigen::Vector3d> first_centres;  // the first frame's, in base_link
  for (int frame = 0; frame < 6; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    const Eigen::Isometry3d& pose = poses[frame % 2];
    const ros::Time stamp = wholeMicroseconds(ros::Time::now());
    tf.publish(worldFromBase(pose, stamp));
    const ObjectsConstPtr objects = sendFrame(stamp);
    ASSERT_NO_FATAL_FAILURE(expectObjectsFound(objects));
    EXPECT_EQ(objects->header.frame_id, "world");
    std::vector<Eigen::Vector3d> centres;
    for (const Solid& solid : solids(*objects)) centres.push_back(pose.inverse() * solid.center);
    if (first_centres.empty()) {
      first_centres = centres;
      continue;
    }
    for (const Eigen::Vector3d& centre : centres) {
      double nearest = INFINITY;
      for (const Eigen::Vector3d& first : first_centres) {
        nearest = std::min(nearest, (centre - first).norm());
      }
      EXPECT_LT(nearest, 0.02) << "an object at (" << centre.transpose()
                               << ") in base_link, not where frame 0 had one";
    }
  }
}

// TF late (issue 16): each frame's transform comes after its cloud. The stages wait for it at
// most ~tf_timeout (set to 1 s for both in tf_late.test): 0.4 s late, every frame is
// processed; 10 s late, the frame is answered before its transform comes, with "no transform"
// as the reason, and the frames after it are processed again: no stall.
TEST_F(PipelineTest, LateTransformIsWaitedForThenReported) {
  ASSERT_NO_FATAL_FAILURE(startFeed());
  ros::Publisher tf = tfPublisher();
  const Eigen::Isometry3d pose(Eigen::Translation3d(1.0, 0.5, 0.0));
  // A frame whose transform is sent `late` s after the cloud; waits for its objects message.
  auto sendLate = [&](double late) {
    const ros::Time stamp = wholeMicroseconds(ros::Time::now());
    scene_.header.stamp = stamp;
    input_.publish(scene_);
    ros::WallDuration(late).sleep();
    tf.publish(worldFromBase(pose, stamp));
    ObjectsConstPtr answer;
    waitFor([&] { return (answer = objectsFor(stamp)) != nullptr; }, 30.0);
    return answer;
  };
  for (int frame = 0; frame < 3; ++frame) {
    SCOPED_TRACE("transform 0.4 s late, frame " + std::to_string(frame));
    expectObjectsFound(sendLate(0.4));
  }
  {
    SCOPED_TRACE("transform 10 s late");
    const double late = 10.0;
    const ros::Time stamp = wholeMicroseconds(ros::Time::now());
    const ros::WallTime sent = ros::WallTime::now();
    const ObjectsConstPtr objects = sendFrame(stamp, late);
    ASSERT_TRUE(objects) << "not answered before its transform came";
    std::printf("frame without its transform answered in %.2f s\n",
                (ros::WallTime::now() - sent).toSec());
    EXPECT_FALSE(objects->table_found);
    EXPECT_EQ(objectCount(*objects), 0u);
    const std::string text = "no transform from up_frame 'world'";
    EXPECT_NE(objects->reason.find(text), std::string::npos) << objects->reason;
    EXPECT_TRUE(waitFor([&] { return logsContaining(text, rosgraph_msgs::Log::WARN) >= 1; }, 5.0))
        << "a warning naming the frame";
    ros::WallDuration(std::max(0.0, late - (ros::WallTime::now() - sent).toSec())).sleep();
    tf.publish(worldFromBase(pose, stamp));
  }
  for (int frame = 0; frame < 2; ++frame) {
    SCOPED_TRACE("after the late one, frame " + std::to_string(frame));
    expectObjectsFound(sendLate(0.0));
  }
}

// A timestamp going backwards (issue 16: a bag played with --loop): the frames' stamps and their
// transforms on /tf (each sent just before its frame, as a bag interleaves them) jump back 30 s,
// more than tf2 keeps (10 s), so tf2 refuses the new transforms as too old until a stage forgets
// the old ones, which it does on the first frame stamped before its last. Both stages warn,
// naming the jump, and every frame gets its objects message. The first frame after the jump
// usually lacks its transform at TableSegmentation (refused before the stage saw the jump), the
// next one at ShapeEstimation (the first frame that stage sees after the jump); from the third
// on every frame has its objects again. Without forgetting, none would.
TEST_F(PipelineTest, StampsGoingBackKeepTheChainRunning) {
  ASSERT_NO_FATAL_FAILURE(startFeed());
  ros::Publisher tf = tfPublisher();
  const Eigen::Isometry3d pose(Eigen::Translation3d(-1.0, 2.0, 0.0));
  ros::Duration back(0.0);  // how far the stamps went back
  auto sendWithTransform = [&] {
    const ros::Time stamp = wholeMicroseconds(ros::Time::now() - back);
    tf.publish(worldFromBase(pose, stamp));
    return sendFrame(stamp);
  };
  for (int frame = 0; frame < 3; ++frame) {
    SCOPED_TRACE("before the jump, frame " + std::to_string(frame));
    expectObjectsFound(sendWithTransform());
  }
  back = ros::Duration(30.0);
  for (int frame = 0; frame < 2; ++frame) {
    const ObjectsConstPtr objects = sendWithTransform();
    ASSERT_TRUE(objects) << "no objects message for frame " << frame << " after the jump";
    std::printf("after the jump, frame %d: %s\n", frame,
                objects->table_found ? "found" : objects->reason.c_str());
    if (!objects->table_found) {
      EXPECT_NE(objects->reason.find("no transform"), std::string::npos) << objects->reason;
    }
  }
  for (int frame = 0; frame < 3; ++frame) {
    SCOPED_TRACE("after the jump, frame " + std::to_string(frame));
    expectObjectsFound(sendWithTransform());
  }
  const std::string text = "frame stamps went back";
  EXPECT_TRUE(waitFor([&] { return logsContaining(text, rosgraph_msgs::Log::WARN) >= 2; }, 5.0))
      << "a warning naming the jump from each stage";
  EXPECT_EQ(logsContaining("more than tf's cache time", rosgraph_msgs::Log::WARN), 2);
}

// A given up that disagrees with the scene (the level-camera guess on a camera looking 40 deg
// down): TableSegmentation warns on /diagnostics and in the log, naming the angle.
TEST_F(PipelineTest, GivenUpDisagreeingWithTheSceneIsWarned) {
  const double timeout = privateParam("timeout", 40.0);
  const std::string given = privateParam<std::string>("given_up", "[0.000, -1.000, 0.000]");
  const double expected_angle = privateParam("expected_angle", 40.0);
  const std::string text = "up " + given + " is ";
  ASSERT_TRUE(waitFor([&] { return warnedOnDiagnostics("table_segmentation", text); }, timeout))
      << "a WARN containing \"" << text << "\"; last: " << lastWarning("table_segmentation");
  const std::string warning = lastWarning("table_segmentation");
  const size_t at = warning.find(text);
  ASSERT_NE(at, std::string::npos) << warning;
  char rest[64] = {};
  double angle = NAN;
  ASSERT_EQ(std::sscanf(warning.c_str() + at + text.size(), "%lf deg from the scene's %63s", &angle,
                        rest),
            2)
      << warning;
  EXPECT_NEAR(angle, expected_angle, 3.0) << warning;
  EXPECT_TRUE(waitFor([&] { return logsContaining(text, rosgraph_msgs::Log::WARN) >= 1; }, 5.0))
      << "a log line containing \"" << text << "\"";
}

// With up estimated (neither up nor up_frame given) the scene's up is used: no up warning.
TEST_F(PipelineTest, EstimatedUpGivesNoUpWarning) {
  ASSERT_TRUE(waitFor([&] { return objectsReceived() >= 3; }, privateParam("timeout", 40.0)));
  EXPECT_FALSE(warnedOnDiagnostics("table_segmentation", "from the scene's up"))
      << lastWarning("table_segmentation");
  EXPECT_EQ(logsContaining("from the scene's up", rosgraph_msgs::Log::WARN), 0);
}

// A stage without input a few seconds after start says so on /diagnostics (WARN) and in the log,
// naming the topic it reads and what the master knows of it (here: no publisher, or one of
// another type, which the test itself publishes when `wrong_type_topic` is set).
TEST_F(PipelineTest, SilentInputNamesTheTopic) {
  const std::string text = privateParam<std::string>("expected_warning", "");
  const std::string stage = privateParam<std::string>("stage", "preprocess");
  const std::string wrong_type_topic = privateParam<std::string>("wrong_type_topic", "");
  ASSERT_FALSE(text.empty());
  ros::NodeHandle node;
  ros::Publisher wrong_type;
  if (!wrong_type_topic.empty()) {
    wrong_type = node.advertise<std_msgs::String>(wrong_type_topic, 1, true);
    std_msgs::String message;
    message.data = "not a cloud";
    wrong_type.publish(message);
  }
  EXPECT_TRUE(waitFor([&] { return warnedOnDiagnostics(stage, text); }, 30.0))
      << "a WARN containing \"" << text << "\"; last: " << lastWarning(stage);
  EXPECT_TRUE(waitFor([&] { return logsContaining(text, rosgraph_msgs::Log::WARN) >= 1; }, 5.0))
      << "a log line containing \"" << text << "\"";
  // Throttled: a standing warning is repeated at most every 10 s, not with every report.
  ros::WallDuration(4.0).sleep();
  EXPECT_LE(logsContaining(text, rosgraph_msgs::Log::WARN), 2);
}

}  // namespace
