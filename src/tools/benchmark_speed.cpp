// benchmark_speed: the core pipeline alone (no ROS) timed per stage on rendered scenes with 1,
// 4, 16 and 32 objects at three resolutions and on the real OSD scenes; prints median / p90 /
// p99 per stage, CPU time per frame, and a scaling table, and writes a gnuplot PNG of the time
// against points and against objects; the main table goes to OUT/speed_core.csv as well, for
// `scripts/benchmark_speed`, which adds the ROS chain and its overhead over the core to it.
//   benchmark_speed [--quick] [--frames N] [--osd DIR] [--out DIR] [--no-plots]
//   benchmark_speed --write-scene OBJECTS PREFIX
#include "tabletop_shapes/core/pipeline.h"
#include "tabletop_shapes/sim/speed_scenes.h"

#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

using namespace tabletop_shapes;
namespace fs = std::filesystem;

namespace {

struct Options {
  int frames = 100;         // timed frames per configuration of the main table
  int scaling_frames = 20;  // per configuration of the scaling table
  int renders = 4;          // noise seeds per rendered configuration, cycled over the frames
  std::string osd_dir;      // real scenes; empty: none
  std::string out_dir = "benchmark-output";
  bool plots = true;
  int write_objects = 0;  // --write-scene: render this scene to write_prefix.pcd and stop
  std::string write_prefix;
};

// One timed configuration: frames of the same scene (or scenes), run back to back.
struct Series {
  std::string key, name;  // key: how scripts/benchmark_speed finds the ROS run of this scene
  std::vector<double> preprocess, table, clustering, shapes, total, cpu;
  double points = 0, objects = 0;  // per frame, mean
};

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t index = std::min(values.size() - 1, static_cast<size_t>(q * values.size()));
  return values[index];
}

double cpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

size_t validPoints(const pcl::PointCloud<pcl::PointXYZ>& cloud) {
  return std::count_if(cloud.begin(), cloud.end(),
                       [](const pcl::PointXYZ& p) { return std::isfinite(p.z); });
}

// Runs `frames` frames cycling over `clouds` (each with its own up, or auto up when empty).
Series timeClouds(const std::string& key, const std::string& name,
                  const std::vector<pcl::PointCloud<pcl::PointXYZ>>& clouds,
                  const std::vector<Eigen::Vector3f>& ups, int frames,
                  const std::function<void()>& tick) {
  Series series;
  series.key = key;
  series.name = name;
  // One pipeline per cloud, as each cloud stands for a camera stream of its own (an estimated
  // up is held between the frames of a stream), then one untimed frame per cloud: buffers
  // sized, caches warm, as in a running chain.
  std::vector<std::unique_ptr<Pipeline>> pipelines;
  for (size_t c = 0; c < clouds.size(); ++c) {
    PipelineParams params;
    params.auto_up = ups.empty();
    if (!ups.empty()) params.table.up = ups[c];
    pipelines.push_back(std::make_unique<Pipeline>(params));
    pipelines.back()->process(clouds[c]);
  }
  double points = 0, objects = 0;
  for (int f = 0; f < frames; ++f) {
    const size_t c = static_cast<size_t>(f) % clouds.size();
    const double cpu_start = cpuMs();
    const SceneResult result = pipelines[c]->process(clouds[c]);
    series.cpu.push_back(cpuMs() - cpu_start);
    series.preprocess.push_back(result.times.preprocess_ms);
    series.table.push_back(result.times.table_ms);
    series.clustering.push_back(result.times.clustering_ms);
    series.shapes.push_back(result.times.shapes_ms);
    series.total.push_back(result.times.total_ms);
    points += static_cast<double>(validPoints(clouds[c]));
    objects += static_cast<double>(result.objects.size());
    tick();
  }
  series.points = points / std::max(frames, 1);
  series.objects = objects / std::max(frames, 1);
  return series;
}

std::vector<pcl::PointCloud<pcl::PointXYZ>> renderClouds(int objects, int width, int height,
                                                         int renders,
                                                         std::vector<Eigen::Vector3f>& ups) {
  std::vector<pcl::PointCloud<pcl::PointXYZ>> clouds(renders);
  ups.clear();
  for (int r = 0; r < renders; ++r) {
    const sim::RenderedScene scene =
        sim::renderScene(sim::speedScene(objects, width, height, static_cast<uint32_t>(r + 1)));
    pcl::copyPointCloud(*scene.cloud, clouds[r]);
    ups.push_back(scene.up);
  }
  return clouds;
}

void printStageTable(const std::vector<Series>& all) {
  std::printf("\nCore pipeline alone (no ROS), one thread calling it; ms per frame\n");
  std::printf("  %-22s %7s %5s  %-17s %-17s %-17s %-17s %-17s %7s\n", "scene", "points", "objs",
              "preprocess", "table", "clustering", "shapes", "total", "CPU ms");
  auto stage = [](const std::vector<double>& v) {
    char text[48];
    std::snprintf(text, sizeof text, "%5.1f/%5.1f/%5.1f", quantile(v, 0.5), quantile(v, 0.9),
                  quantile(v, 0.99));
    return std::string(text);
  };
  for (const Series& s : all) {
    std::printf("  %-22s %7.0f %5.1f  %-17s %-17s %-17s %-17s %-17s %7.1f\n", s.name.c_str(),
                s.points, s.objects, stage(s.preprocess).c_str(), stage(s.table).c_str(),
                stage(s.clustering).c_str(), stage(s.shapes).c_str(), stage(s.total).c_str(),
                quantile(s.cpu, 0.5));
  }
  std::printf(
      "  (each stage and the total: median/p90/p99 ms; CPU ms: median process CPU time per frame,"
      " all threads)\n");
}

// The main table's medians for scripts/benchmark_speed (the ROS chain's overhead over the core).
void writeCoreCsv(const std::vector<Series>& all, const std::string& path) {
  FILE* file = std::fopen(path.c_str(), "w");
  if (!file) {
    std::fprintf(stderr, "benchmark_speed: cannot write %s\n", path.c_str());
    return;
  }
  std::fprintf(file, "key,preprocess,table,clustering,shapes,total,total_p90,total_p99,cpu\n");
  for (const Series& s : all) {
    std::fprintf(file, "%s,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n", s.key.c_str(),
                 quantile(s.preprocess, 0.5), quantile(s.table, 0.5), quantile(s.clustering, 0.5),
                 quantile(s.shapes, 0.5), quantile(s.total, 0.5), quantile(s.total, 0.9),
                 quantile(s.total, 0.99), quantile(s.cpu, 0.5));
  }
  std::fclose(file);
}

struct ScalingRow {
  int width, height, objects;
  Series series;
};

void writePlot(const std::vector<ScalingRow>& rows, const Options& options) {
  const std::string data = options.out_dir + "/speed_scaling.dat";
  FILE* file = std::fopen(data.c_str(), "w");
  if (!file) return;
  std::fprintf(file, "# width height objects points median_ms p90_ms\n");
  for (const ScalingRow& row : rows) {
    std::fprintf(file, "%d %d %d %.0f %.3f %.3f\n", row.width, row.height, row.objects,
                 row.series.points, quantile(row.series.total, 0.5),
                 quantile(row.series.total, 0.9));
  }
  std::fclose(file);
  const std::string png = options.out_dir + "/speed_scaling.png";
  const std::string script_path = options.out_dir + "/speed_scaling.gp";
  FILE* script = std::fopen(script_path.c_str(), "w");
  if (!script) return;
  std::fprintf(script,
               "set terminal pngcairo size 1100,450 noenhanced\n"
               "set output '%s'\n"
               "set multiplot layout 1,2 title 'tabletop_shapes core alone, median ms per frame'\n"
               "set grid; set key top left; set ylabel 'ms per frame'\n"
               "set xlabel 'valid points in the frame'\n"
               "plot for [n in '1 4 16 32'] '%s' using ($3==n+0 ? $4 : 1/0):5"
               " with linespoints title n.' objects'\n"
               "set xlabel 'objects on the table'\n"
               "plot for [w in '320 640 1280'] '%s' using ($1==w+0 ? $3 : 1/0):5"
               " with linespoints title w.' px wide'\n"
               "unset multiplot\n",
               png.c_str(), data.c_str(), data.c_str());
  std::fclose(script);
  const std::string command = "gnuplot '" + script_path + "' 2>/dev/null";
  if (std::system(command.c_str()) == 0) {
    std::printf("\nPlot: %s (data %s)\n", png.c_str(), data.c_str());
  } else {
    std::printf("\n(gnuplot failed; data in %s)\n", data.c_str());
  }
}

Options parse(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "benchmark_speed: %s needs a value\n", arg.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--quick") {
      options.frames = 5;
      options.scaling_frames = 2;
      options.renders = 1;
    } else if (arg == "--frames") {
      options.frames = std::max(1, std::atoi(value().c_str()));
    } else if (arg == "--osd") {
      options.osd_dir = value();
    } else if (arg == "--out") {
      options.out_dir = value();
    } else if (arg == "--no-plots") {
      options.plots = false;
    } else if (arg == "--write-scene") {
      options.write_objects = std::max(1, std::atoi(value().c_str()));
      options.write_prefix = value();
    } else {
      std::fprintf(stderr,
                   "usage: benchmark_speed [--quick] [--frames N] [--osd DIR] [--out DIR]"
                   " [--no-plots]\n"
                   "       benchmark_speed --write-scene OBJECTS PREFIX   (the VGA scene as PCD +"
                   " JSON, e.g. for callgrind runs of estimate_shapes)\n");
      std::exit(2);
    }
  }
  return options;
}

}  // namespace

int main(int argc, char** argv) {
  const Options options = parse(argc, argv);
  if (options.write_objects > 0) {
    const sim::RenderedScene scene = sim::renderScene(sim::speedScene(options.write_objects));
    const bool written = sim::writePcd(scene, options.write_prefix + ".pcd") &&
                         sim::writeGroundTruthJson(scene, options.write_prefix + ".json");
    std::printf("%s.pcd: %d objects, up %g,%g,%g\n", options.write_prefix.c_str(),
                options.write_objects, scene.up.x(), scene.up.y(), scene.up.z());
    return written ? 0 : 1;
  }
  fs::create_directories(options.out_dir);

  struct Config {
    int width, height, objects;
  };
  const std::vector<Config> main_configs = {{640, 480, 1}, {640, 480, 4}, {640, 480, 16}};
  std::vector<Config> scaling_configs;
  for (const Config& size : {Config{320, 240, 0}, Config{640, 480, 0}, Config{1280, 1024, 0}}) {
    for (int objects : {1, 4, 16, 32})
      scaling_configs.push_back({size.width, size.height, objects});
  }
  std::vector<fs::path> osd_files;
  if (!options.osd_dir.empty()) {
    for (const auto& entry : fs::directory_iterator(options.osd_dir)) {
      if (entry.path().extension() == ".pcd" &&
          entry.path().filename().string().rfind("learn", 0) == 0) {
        osd_files.push_back(entry.path());
      }
    }
    std::sort(osd_files.begin(), osd_files.end());
  }

  const int total = static_cast<int>(main_configs.size()) * options.frames +
                    (osd_files.empty() ? 0 : options.frames) +
                    static_cast<int>(scaling_configs.size()) * options.scaling_frames;
  int done = 0;
  std::string current;
  auto tick = [&]() {
    ++done;
    std::fprintf(stderr, "\r[core] %-24s %5d / %d frames", current.c_str(), done, total);
    std::fflush(stderr);
  };

  std::vector<Series> series;
  std::vector<Eigen::Vector3f> ups;
  for (const Config& config : main_configs) {
    current = "VGA " + std::to_string(config.objects) + " objects";
    const auto clouds =
        renderClouds(config.objects, config.width, config.height, options.renders, ups);
    series.push_back(timeClouds("vga" + std::to_string(config.objects), current, clouds, ups,
                                options.frames, tick));
  }
  if (!osd_files.empty()) {
    current = "OSD learn (" + std::to_string(osd_files.size()) + " scenes)";
    std::vector<pcl::PointCloud<pcl::PointXYZ>> clouds;
    for (const fs::path& file : osd_files) {
      pcl::PointCloud<pcl::PointXYZ> cloud;
      if (pcl::io::loadPCDFile(file.string(), cloud) >= 0) clouds.push_back(std::move(cloud));
    }
    if (!clouds.empty()) {
      series.push_back(timeClouds("osd", current, clouds, {}, options.frames, tick));
    }
  }
  std::vector<ScalingRow> rows;
  for (const Config& config : scaling_configs) {
    current = std::to_string(config.width) + "x" + std::to_string(config.height) + " " +
              std::to_string(config.objects) + " objects";
    const auto clouds =
        renderClouds(config.objects, config.width, config.height, options.renders, ups);
    rows.push_back({config.width, config.height, config.objects,
                    timeClouds("", current, clouds, ups, options.scaling_frames, tick)});
  }
  std::fprintf(stderr, "\n");

  printStageTable(series);
  writeCoreCsv(series, options.out_dir + "/speed_core.csv");
  std::printf("\nScaling (core alone, median / p90 ms per frame, %d frames each)\n",
              options.scaling_frames);
  std::printf("  %-10s %7s %9s %8s %8s %8s\n", "image", "objects", "points", "found", "median",
              "p90");
  for (const ScalingRow& row : rows) {
    std::printf("  %4dx%-5d %7d %9.0f %8.1f %8.1f %8.1f\n", row.width, row.height, row.objects,
                row.series.points, row.series.objects, quantile(row.series.total, 0.5),
                quantile(row.series.total, 0.9));
  }
  // The cost of one more object at VGA: slope of the median between 1 and 32 objects.
  const Series* one = nullptr;
  const Series* many = nullptr;
  for (const ScalingRow& row : rows) {
    if (row.width == 640 && row.objects == 1) one = &row.series;
    if (row.width == 640 && row.objects == 32) many = &row.series;
  }
  if (one && many) {
    std::printf("  per extra object at 640x480 (1 -> 32 objects): %.2f ms\n",
                (quantile(many->total, 0.5) - quantile(one->total, 0.5)) / 31.0);
  }
  std::printf("  (wall times of one run on a shared machine: compare ratios, not absolutes)\n");
  if (options.plots) writePlot(rows, options);
  return 0;
}
