// "Up" as a user gives it, in one syntax for the command (--up), the launch file (up:=) and the
// rosparam (~up): "auto" (or empty) estimates it from the scene; "X,Y,Z" or "[x, y, z]" is a
// vector in the cloud frame. And the check that a given up fits the scene.
#pragma once

#include "tabletop_shapes/core/table_segmentation.h"

#include <string>

namespace tabletop_shapes {

struct UpSetting {
  bool automatic = true;                             // estimate up from the scene
  Eigen::Vector3f vector = Eigen::Vector3f::Zero();  // unit, when !automatic
};

// Parses "auto", "" (auto), "X,Y,Z" and "[x, y, z]" (spaces anywhere). Returns false with a
// reason naming the text for anything else (wrong count, not numbers, zero or non-finite).
bool parseUp(const std::string& text, UpSetting& up, std::string& error);

// "[x, y, z]" with 3 decimals: how up is shown in logs and in the launch file's syntax.
std::string formatUp(const Eigen::Vector3f& up);

// How well the up used for the table fits the scene.
struct UpCheck {
  bool scene_up_found = false;                         // estimateUp found level planes
  Eigen::Vector3f scene_up = Eigen::Vector3f::Zero();  // up estimated from the scene
  // The table holds most of the scene's points (tableIsTheDominantLevelPlane): scene_up is its
  // normal, and estimateUp's plane search (as costly as the table stage) was not needed.
  bool from_table = false;
  float up_angle_deg = 0.0f;     // between the given up and the scene's up
  float table_angle_deg = 0.0f;  // between the chosen table's normal and the scene's up
  std::string warning;           // empty when both lie within up_tolerance_deg
};

// Compares `params.up` and, when found, the table chosen with it against the up the scene
// shows (estimateUp): a given up that is off by more than up_tolerance_deg finds a wrong
// "table" (a wall, a box side) and wrong objects while looking fine, so it gets a warning.
// A table holding most of the scene's points is the scene's up itself (UpCheck::from_table).
UpCheck checkUpAgainstScene(const CloudConstPtr& cloud, const TableParams& params,
                            const TableResult& table);

// "Up" estimated from the scene of a camera stream: estimateUp is a plane search over the whole
// frame (as costly as the table search itself), and up moves only when the camera turns. So
// the estimate is held and made again every `reestimate_frames` frames, and at once when the
// held up finds no table (the camera turned past up_tolerance_deg). One per stream (a
// Pipeline, a nodelet); a still camera gets the same up, table and objects as with an estimate
// in every frame.
class UpEstimate {
 public:
  explicit UpEstimate(int reestimate_frames = 30);

  // The table of `cloud` with up from the scene; `params.up` is set to the up used. False, with
  // table.reason saying why, when the scene shows no plane to take up from.
  bool segment(const CloudConstPtr& cloud, TableParams& params, TableResult& table);

 private:
  int reestimate_frames_;
  int frames_since_estimate_ = 0;
  bool held_ = false;
  Eigen::Vector3f up_ = Eigen::Vector3f::Zero();
};

}  // namespace tabletop_shapes
