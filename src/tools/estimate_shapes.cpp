// estimate_shapes: the whole pipeline on one PCD file, the result as one JSON document.
//   estimate_shapes [--up X,Y,Z | --up [x,y,z] | --up auto] [--config PARAMS.yaml]
//                   [--max-points N] CLOUD.pcd
// Without --up, up is estimated from the scene (auto); a given up that disagrees with the
// scene's is reported under "warnings" (and on stderr).
// Exit 0 when the cloud was processed (also without a table), 2 for bad usage, an unreadable
// or inconsistent file (named in one line) or a cloud without x y z, 1 for an unexpected
// internal error.
#include "tabletop_shapes/core/parameter_table.h"
#include "tabletop_shapes/core/pipeline.h"
#include "tabletop_shapes/core/up_direction.h"

#include "tabletop_shapes/core/pcd_reader.h"

#include <pcl/console/print.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>

using namespace tabletop_shapes;

namespace {

const char* kUsage =
    "usage: estimate_shapes [--up X,Y,Z | --up auto] [--config PARAMS.yaml] [--max-points N]\n"
    "                       CLOUD.pcd   (ascii, binary or binary_compressed; N default 4000000)\n"
    "       --up: up in the cloud frame, X,Y,Z or [x,y,z]; auto (the default) estimates it\n"
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
  std::string error;
  if (!validateParams(params, error)) throw UsageError("config " + path + ": " + error);
}

// Any PCD with x y z (float32 or float64); other fields (rgb, label, normals) are ignored.
// Our bounded reader, not PCL's: see core/pcd_reader.h.
pcl::PointCloud<pcl::PointXYZ> loadCloud(const std::string& path, const PcdReadOptions& options) {
  try {
    return readPcdFile(path, options);
  } catch (const PcdError& e) {
    throw UsageError("cannot read PCD file " + path + ": " + e.what());
  }
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
  json.key("warnings").raw("[");
  if (!scene.up_warning.empty()) json.string(scene.up_warning);
  json.raw("],\n ");
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
  // Clusters that are no objects on the table, with the reason: nothing is dropped silently.
  json.key("rejected").raw("[");
  for (size_t i = 0; i < scene.rejected.size(); ++i) {
    const RejectedCluster& r = scene.rejected[i];
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (const Point& p : r.points->points) centroid += p.getVector3fMap();
    centroid /= static_cast<float>(std::max<size_t>(r.points->size(), 1));
    json.raw(i ? ",\n  {" : "\n  {").key("center").array(centroid, 3).raw(", ");
    json.key("points").number(static_cast<double>(r.points->size())).raw(", ");
    json.key("reason").string(r.reason).raw("}");
  }
  json.raw(scene.rejected.empty() ? "],\n " : "\n ],\n ");
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
  PcdReadOptions read_options;
  params.auto_up = true;  // a safe default: a fixed guess suits only a level camera
  params.check_up = true;
  std::string cloud_path;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw UsageError(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--up") {
      UpSetting up;
      std::string error;
      if (!parseUp(value(), up, error)) throw UsageError("--up: " + error);
      params.auto_up = up.automatic;
      if (!up.automatic) params.table.up = up.vector;
    } else if (arg == "--config") {
      loadConfig(value(), params);
    } else if (arg == "--max-points") {
      const std::string text = value();
      char* end = nullptr;
      const unsigned long long n = std::strtoull(text.c_str(), &end, 10);
      if (text.empty() || *end || text[0] == '-' || n == 0) {
        throw UsageError("--max-points wants a positive integer, got '" + text + "'");
      }
      read_options.max_points = n;
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

  const pcl::PointCloud<pcl::PointXYZ> cloud = loadCloud(cloud_path, read_options);
  Pipeline pipeline(params);
  const SceneResult result = pipeline.process(cloud);
  if (!result.up_warning.empty())
    std::cerr << "estimate_shapes: warning: " << result.up_warning << "\n";
  std::cout << toJson(result) << std::flush;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // The core's PCL algorithms may print; our one line on stderr is the one that matters.
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
