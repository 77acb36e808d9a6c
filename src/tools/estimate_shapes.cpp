// estimate_shapes: the whole pipeline on one PCD file, the result as one JSON document.
//   estimate_shapes [--up X,Y,Z | --up auto] [--config PARAMS.yaml] CLOUD.pcd
// Exit 0 when the cloud was processed (also without a table), 2 for bad usage, an unreadable
// file or a cloud without x y z, 1 for an unexpected internal error.
#include "tabletop_shapes/core/parameter_table.h"
#include "tabletop_shapes/core/pipeline.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <iostream>
#include <sstream>

using namespace tabletop_shapes;

namespace {

const char* kUsage =
    "usage: estimate_shapes [--up X,Y,Z | --up auto] [--config PARAMS.yaml] CLOUD.pcd\n"
    "       estimate_shapes --parameters   (every parameter, its default and range)";

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Minimal JSON output: numbers with 6 significant digits (sub-millimetre in metres).
class Json {
 public:
  std::string str() const { return out_.str(); }
  Json& raw(const std::string& text) {
    out_ << text;
    return *this;
  }
  Json& key(const char* name) {
    out_ << '"' << name << "\": ";
    return *this;
  }
  Json& number(double v) {
    if (!std::isfinite(v)) {
      out_ << "null";
    } else {
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "%.6g", v);
      out_ << buffer;
    }
    return *this;
  }
  Json& string(const std::string& s) {
    out_ << '"';
    for (char c : s) {
      if (c == '"' || c == '\\')
        out_ << '\\' << c;
      else if (static_cast<unsigned char>(c) < 0x20)
        out_ << ' ';
      else
        out_ << c;
    }
    out_ << '"';
    return *this;
  }
  template <typename Vector>
  Json& array(const Vector& v, int n) {
    out_ << '[';
    for (int i = 0; i < n; ++i) {
      if (i) out_ << ", ";
      number(v[i]);
    }
    out_ << ']';
    return *this;
  }

 private:
  std::ostringstream out_;
};

Eigen::Vector3f parseVector(const std::string& text) {
  std::istringstream in(text);
  Eigen::Vector3f v;
  char comma1 = 0, comma2 = 0;
  if (!(in >> v.x() >> comma1 >> v.y() >> comma2 >> v.z()) || comma1 != ',' || comma2 != ',' ||
      !in.eof() || !v.allFinite() || v.norm() < 1e-6f) {
    throw UsageError("--up wants X,Y,Z (a non-zero vector) or auto, got '" + text + "'");
  }
  return v.normalized();
}

void loadConfig(const std::string& path, PipelineParams& params) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw UsageError("cannot read config " + path + ": " + e.what());
  }
  if (root.IsNull()) return;
  if (!root.IsMap()) throw UsageError("config " + path + ": expected 'stage: {name: value}'");
  for (const auto& stage : root) {
    const std::string stage_name = stage.first.as<std::string>();
    if (!stage.second.IsMap()) {
      throw UsageError("config " + path + ": '" + stage_name + "' should hold name: value pairs");
    }
    for (const auto& entry : stage.second) {
      const std::string name = entry.first.as<std::string>();
      double value = 0;
      try {
        value = entry.second.as<double>();
      } catch (const YAML::Exception&) {
        throw UsageError("config " + path + ": " + stage_name + "." + name + " is not a number");
      }
      std::string error;
      if (!setParameter(params, stage_name, name, value, error)) {
        throw UsageError("config " + path + ": " + error);
      }
    }
  }
}

// PCL's PCD reader crashes on some malformed files (random bytes: a segfault), so the header is
// checked first: every line up to DATA must be a known PCD keyword, the sizes must be sane, and
// a binary body must be as long as the header says.
void checkPcdHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UsageError("cannot read PCD file " + path);
  const std::set<std::string> keywords = {"VERSION", "FIELDS", "SIZE",      "TYPE",  "COUNT",
                                          "WIDTH",   "HEIGHT", "VIEWPOINT", "POINTS"};
  std::string line, data;
  long long points = -1, point_size = 0;
  for (int lines = 0; lines < 64 && std::getline(in, line); ++lines) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "DATA") {
      words >> data;
      break;
    }
    if (!keywords.count(keyword))
      throw UsageError("cannot read PCD file " + path + ": not a PCD header");
    if (keyword == "POINTS" && !(words >> points)) points = -2;
    if (keyword == "SIZE") {
      for (long long size; words >> size;) point_size += size;
    }
  }
  if (data != "ascii" && data != "binary" && data != "binary_compressed") {
    throw UsageError("cannot read PCD file " + path + ": no DATA ascii|binary|binary_compressed");
  }
  if (points < 0 || points > 100000000) {
    throw UsageError("cannot read PCD file " + path + ": bad POINTS");
  }
  const std::streamoff body_start = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff body = in.tellg() - body_start;
  if (data == "binary" && body < points * point_size) {
    throw UsageError("cannot read PCD file " + path + ": truncated (binary body too short)");
  }
  if (data == "binary_compressed" && points > 0 && body < 8) {
    throw UsageError("cannot read PCD file " + path + ": truncated (no compressed body)");
  }
}

// Any PCD with x y z; rgb and other fields (label, normals) are ignored.
pcl::PointCloud<pcl::PointXYZ> loadCloud(const std::string& path) {
  checkPcdHeader(path);
  pcl::PCLPointCloud2 blob;
  if (pcl::io::loadPCDFile(path, blob) < 0) throw UsageError("cannot read PCD file " + path);
  for (const char* field : {"x", "y", "z"}) {
    bool present = false;
    for (const auto& f : blob.fields) present |= f.name == field;
    if (!present) throw UsageError(path + " has no '" + field + "' field");
  }
  pcl::PointCloud<pcl::PointXYZ> cloud;
  pcl::fromPCLPointCloud2(blob, cloud);
  return cloud;
}

// The extents of a truncated object that are lower bounds, as a JSON list of names: a box's
// "x", "y", "z" (its dimensions), a round solid's "radius", "height".
std::string lowerBoundNames(const ShapeFit& fit) {
  const bool cube = fit.type == ShapeType::Cube;
  const char* names[3] = {cube ? "x" : "radius", cube ? "y" : nullptr, cube ? "z" : "height"};
  std::string list = "[";
  for (int i = 0; i < 3; ++i) {
    if (!fit.lower_bound[i] || !names[i]) continue;
    list += std::string(list.size() > 1 ? ", " : "") + '"' + names[i] + '"';
  }
  return list + "]";
}

std::string toJson(const SceneResult& scene) {
  Json json;
  json.raw("{").key("status").string(scene.table.found ? "ok" : "no table").raw(",\n ");
  if (!scene.table.found && !scene.table.reason.empty()) {
    json.key("reason").string(scene.table.reason).raw(",\n ");
  }
  json.key("up").array(scene.up, 3).raw(",\n ");
  json.key("table");
  if (scene.table.found) {
    json.raw("{").key("coefficients").array(scene.table.plane.coefficients(), 4).raw(", ");
    json.key("inliers").number(scene.table.inliers).raw("}");
  } else {
    json.raw("null");
  }
  json.raw(",\n ").key("objects").raw("[");
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const ShapeFit& o = scene.objects[i];
    json.raw(i ? ",\n  {" : "\n  {").key("id").number(static_cast<double>(i)).raw(", ");
    json.key("type").string(shapeTypeName(o.ok ? o.type : ShapeType::Unknown)).raw(", ");
    json.key("center").array(o.center, 3).raw(", ");
    if (!o.ok) {
      json.key("points").number(o.points).raw(", ").key("reason").string(o.reason).raw("}");
      continue;
    }
    if (o.type == ShapeType::Cube) {
      const Eigen::Vector4f q = o.orientation.coeffs();  // x, y, z, w
      json.key("orientation").array(q, 4).raw(", ");
      json.key("dimensions").array(o.dimensions, 3).raw(", ");
    } else {
      json.key("axis").array(o.axis(), 3).raw(", ");
      if (o.type == ShapeType::Cylinder) {
        json.key("radius").number(o.radius).raw(", ");
      } else {
        json.key("radius_bottom").number(o.radius_bottom).raw(", ");
        json.key("radius_top").number(o.radius_top).raw(", ");
      }
      json.key("height").number(o.height).raw(", ");
    }
    json.key("points").number(o.points).raw(", ").key("rmse").number(o.rmse);
    if (o.type == ShapeType::Cube) {
      json.raw(", ").key("faces_seen").number(o.faces_seen);
      json.raw(", ").key("bounding_box").raw(o.bounding_box ? "true" : "false");
      if (o.bounding_box) json.raw(", ").key("reason").string(o.reason);
    }
    json.raw(", ").key("truncated").raw(o.truncated ? "true" : "false");
    if (o.truncated) json.raw(", ").key("lower_bounds").raw(lowerBoundNames(o));
    json.raw("}");
  }
  json.raw(scene.objects.empty() ? "],\n " : "\n ],\n ");
  const StageTimes& t = scene.times;
  json.key("timing_ms").raw("{").key("preprocess").number(t.preprocess_ms).raw(", ");
  json.key("table").number(t.table_ms).raw(", ").key("clustering").number(t.clustering_ms);
  json.raw(", ").key("shapes").number(t.shapes_ms).raw(", ").key("total").number(t.total_ms);
  json.raw("}}\n");
  return json.str();
}

// Every tunable as a Markdown table (the README's parameter section is this output).
void printParameterTable() {
  PipelineParams defaults;
  std::cout << "| parameter | default | range | meaning |\n|---|---|---|---|\n";
  forEachParameter(defaults, [](const ParameterInfo& info, double& value) {
    std::cout << "| `" << info.stage << "." << info.name << "` | " << value << " | " << info.min
              << " .. " << info.max << " | " << info.description << " |\n";
  });
}

int run(int argc, char** argv) {
  PipelineParams params;
  std::string cloud_path;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw UsageError(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--up") {
      const std::string up = value();
      params.auto_up = up == "auto";
      if (!params.auto_up) params.table.up = parseVector(up);
    } else if (arg == "--config") {
      loadConfig(value(), params);
    } else if (arg == "--parameters") {
      printParameterTable();
      return 0;
    } else if (arg == "-h" || arg == "--help") {
      std::cout << kUsage << "\n";
      return 0;
    } else if (!arg.empty() && arg[0] == '-') {
      throw UsageError("unknown option " + arg);
    } else if (cloud_path.empty()) {
      cloud_path = arg;
    } else {
      throw UsageError("one cloud at a time: got '" + cloud_path + "' and '" + arg + "'");
    }
  }
  if (cloud_path.empty()) throw UsageError("no cloud given");

  const pcl::PointCloud<pcl::PointXYZ> cloud = loadCloud(cloud_path);
  Pipeline pipeline(params);
  std::cout << toJson(pipeline.process(cloud)) << std::flush;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // PCL's reader prints its own complaints; our one line on stderr is the one that matters.
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  try {
    return run(argc, argv);
  } catch (const UsageError& e) {
    std::cerr << "estimate_shapes: " << e.what() << "\n" << kUsage << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "estimate_shapes: internal error: " << e.what() << "\n";
    return 1;
  }
}
