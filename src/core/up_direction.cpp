#include "tabletop_shapes/core/up_direction.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace tabletop_shapes {
namespace {

std::string trim(const std::string& text) {
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  return text.substr(first, text.find_last_not_of(" \t\r\n") - first + 1);
}

float angleDeg(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  const float cosine = std::max(-1.0f, std::min(1.0f, a.normalized().dot(b.normalized())));
  return std::acos(cosine) * 180.0f / static_cast<float>(kPi);
}

}  // namespace

bool parseUp(const std::string& text, UpSetting& up, std::string& error) {
  const std::string why =
      "up must be auto, X,Y,Z or [x, y, z] (a non-zero vector in the cloud "
      "frame), got '" +
      text + "'";
  std::string body = trim(text);
  if (body.empty() || body == "auto") {
    up = UpSetting{};
    return true;
  }
  if (body.front() == '[' || body.back() == ']') {
    if (body.size() < 2 || body.front() != '[' || body.back() != ']') {
      error = why;
      return false;
    }
    body = body.substr(1, body.size() - 2);
  }
  Eigen::Vector3f vector;
  size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const size_t comma = body.find(',', start);
    if ((i < 2) == (comma == std::string::npos)) {  // exactly two commas
      error = why;
      return false;
    }
    const std::string number =
        trim(body.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    char* end = nullptr;
    vector[i] = std::strtof(number.c_str(), &end);
    if (number.empty() || *end != '\0') {
      error = why;
      return false;
    }
    start = comma + 1;
  }
  if (!vector.allFinite() || vector.norm() < 1e-6f) {
    error = why;
    return false;
  }
  up.automatic = false;
  up.vector = vector.normalized();
  return true;
}

std::string formatUp(const Eigen::Vector3f& up) {
  char text[96];
  std::snprintf(text, sizeof text, "[%.3f, %.3f, %.3f]", up.x(), up.y(), up.z());
  return text;
}

UpCheck checkUpAgainstScene(const CloudConstPtr& cloud, const TableParams& params,
                            const TableResult& table) {
  UpCheck check;
  if (cloud && tableIsTheDominantLevelPlane(*cloud, table)) {
    check.from_table = check.scene_up_found = true;
    check.scene_up = table.plane.normal;
  } else {
    check.scene_up_found = estimateUp(cloud, params, check.scene_up);
  }
  if (!check.scene_up_found) return check;
  check.up_angle_deg = angleDeg(params.up, check.scene_up);
  if (table.found) check.table_angle_deg = angleDeg(table.plane.normal, check.scene_up);
  const float worst = std::max(check.up_angle_deg, check.table_angle_deg);
  if (worst > params.up_tolerance_deg) {
    char text[160];
    std::snprintf(text, sizeof text, "up %s is %.0f deg from the scene's up %s (its level planes)",
                  formatUp(params.up).c_str(), check.up_angle_deg,
                  formatUp(check.scene_up).c_str());
    check.warning = text;
    if (table.found) {
      std::snprintf(text, sizeof text, ", the chosen table plane %.0f deg", check.table_angle_deg);
      check.warning += text;
    }
    check.warning +=
        ": the table and objects found are likely wrong; check up / up_frame, or give neither "
        "to estimate up from the scene";
  }
  return check;
}

UpEstimate::UpEstimate(int reestimate_frames)
    : reestimate_frames_(std::max(reestimate_frames, 1)) {}

bool UpEstimate::segment(const CloudConstPtr& cloud, TableParams& params, TableResult& table) {
  const bool reuse = held_ && frames_since_estimate_ < reestimate_frames_;
  if (reuse) {
    ++frames_since_estimate_;
    params.up = up_;
    table = TableSegmenter(params).segment(cloud);
    if (table.found) return true;
  }
  frames_since_estimate_ = 1;
  held_ = estimateUp(cloud, params, up_);
  if (!held_) {
    table = TableResult();
    table.reason = "no large plane with the camera above it to take 'up' from";
    return false;
  }
  params.up = up_;
  table = TableSegmenter(params).segment(cloud);
  return true;
}

}  // namespace tabletop_shapes
