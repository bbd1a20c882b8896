// clutterseg-segment: segments organized point clouds (PCD) or depth PNGs into objects and
// writes a labelled PCD, the objects as JSON and an overlay PNG.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "clutterseg/config/daemon_config.h"
#include "clutterseg/core/json_writer.h"
#include "clutterseg/core/text_and_color.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/pipeline/overlay.h"
#include "clutterseg/pipeline/segmenter.h"

namespace fs = std::filesystem;
using namespace clutterseg;

namespace {

constexpr int kExitOk = 0;
constexpr int kExitData = 1;
constexpr int kExitUsage = 2;

struct Options {
  std::string input;
  std::string output;
  std::string config_file;
  std::vector<std::string> overrides;
  std::string json_out;
  std::string png_out;
  std::string intrinsics_file;
  std::string color_png;
  std::string times_out;
  double depth_scale_to_mm{1.0};
  int threads{0};
  int lanes{0};
  bool quiet{false};
};

void WriteObjectsJson(const std::string& path, const std::string& source,
                      const pipeline::SegmentationResult& r) {
  core::JsonWriter j;
  j.BeginObject();
  j.Field("source", source);
  j.Field("width", r.width).Field("height", r.height);
  j.Field("num_valid_points", r.num_valid_points).Field("num_supervoxels", r.num_supervoxels);
  j.Key("planes").BeginArray();
  for (const pipeline::Plane& p : r.planes) {
    j.BeginObject();
    j.Field("id", p.id);
    j.Array("normal", {p.normal.x, p.normal.y, p.normal.z});
    j.Field("d", p.d).Field("num_points", p.num_points).Field("is_support", p.is_support);
    j.EndObject();
  }
  j.EndArray();
  j.Key("objects").BeginArray();
  for (const pipeline::Object& o : r.objects) {
    j.BeginObject();
    j.Field("id", o.id).Field("num_points", o.num_points);
    j.Array("centroid", {o.centroid.x, o.centroid.y, o.centroid.z});
    j.Array("aabb_min", {o.aabb_min.x, o.aabb_min.y, o.aabb_min.z});
    j.Array("aabb_max", {o.aabb_max.x, o.aabb_max.y, o.aabb_max.z});
    j.Array("obb_center", {o.obb_center.x, o.obb_center.y, o.obb_center.z});
    j.Key("obb_axes").BeginArray();
    for (const core::Vec3f& a : o.obb_axes) {
      j.BeginArray().Value(a.x).Value(a.y).Value(a.z).EndArray();
    }
    j.EndArray();
    j.Array("obb_extents", {o.obb_extents.x, o.obb_extents.y, o.obb_extents.z});
    j.Field("support_plane_id", o.support_plane_id);
    j.Array("mean_color", {double(o.mean_color.r), double(o.mean_color.g), double(o.mean_color.b)});
    j.Field("confidence", o.confidence);
    j.Array("pixel_bbox", {double(o.pixel_min_u), double(o.pixel_min_v), double(o.pixel_max_u),
                           double(o.pixel_max_v)});
    j.EndObject();
  }
  j.EndArray();
  j.Key("times_ms").BeginObject();
  const pipeline::StageTimes& t = r.times;
  j.Field("points", t.points_ms).Field("supervoxels", t.supervoxels_ms);
  j.Field("voxelize", t.voxelize_ms).Field("normals", t.normals_ms);
  j.Field("features", t.features_ms).Field("linkage", t.linkage_ms);
  j.Field("planes", t.planes_ms).Field("objects", t.objects_ms).Field("total", t.total_ms);
  j.EndObject();
  j.EndObject();
  std::ofstream f(path);
  f << j.str() << "\n";
  if (!f) throw std::runtime_error(path + ": cannot write objects JSON");
}

bool IsPng(const fs::path& p) { return p.extension() == ".png" || p.extension() == ".PNG"; }

// Loads `in` into `cloud`, reusing its storage (a PCD after another allocates nothing).
void LoadInput(const fs::path& in, const Options& opt, core::PointCloud* cloud,
               core::CameraIntrinsics* intrinsics) {
  if (IsPng(in)) {
    *intrinsics = opt.intrinsics_file.empty() ? core::DefaultKinectIntrinsics()
                                              : io::ReadIntrinsicsJson(opt.intrinsics_file);
    *cloud = io::ReadDepthPngCloud(in.string(), *intrinsics, opt.color_png, opt.depth_scale_to_mm);
    return;
  }
  io::ReadPcd(in.string(), io::ReadLimits{}, cloud);
  if (!cloud->organized()) {
    throw std::runtime_error(in.string() +
                             ": the cloud is not organized (HEIGHT 1); clutterseg-segment needs an "
                             "organized depth image layout");
  }
  *intrinsics = opt.intrinsics_file.empty() ? core::DefaultKinectIntrinsics()
                                            : io::ReadIntrinsicsJson(opt.intrinsics_file);
  if (intrinsics->width != cloud->width || intrinsics->height != cloud->height) {
    *intrinsics = intrinsics->Scaled(cloud->width, cloud->height);
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  CLI::App app{
      "Segments an organized point cloud (PCD) or a depth PNG into objects.\n"
      "IN and OUT may also be two directories: every *.pcd / *.png of IN is segmented into "
      "OUT/<name>.pcd (then --json and --png name directories)."};
  app.add_option("IN", opt.input, "input .pcd, depth .png (millimetres), or a directory")
      ->required();
  app.add_option("OUT", opt.output, "output labelled .pcd (x y z rgba label), or a directory")
      ->required();
  app.add_option("--config", opt.config_file, "YAML config; its segmenter: section is used");
  app.add_option("--set", opt.overrides,
                 "override a segmenter parameter, e.g. --set supervoxel.seed_resolution_m=0.02");
  app.add_option("--json", opt.json_out, "write the objects and planes as JSON");
  app.add_option("--png", opt.png_out, "write an overlay PNG of the objects");
  app.add_option("--intrinsics", opt.intrinsics_file,
                 "camera intrinsics JSON (default fx=fy=525, cx=319.5, cy=239.5)");
  app.add_option("--color", opt.color_png, "colour PNG registered to a depth PNG input");
  app.add_option("--depth-scale", opt.depth_scale_to_mm,
                 "multiply depth PNG values by this to get millimetres (TUM: 0.2)");
  app.add_option("--threads", opt.threads, "worker threads (0 = number of cores)")
      ->check(CLI::Range(0, 256));
  app.add_option("--lanes", opt.lanes,
                 "frames of a directory segmented at once (0 = 2 when the pool has 2 threads "
                 "or more)")
      ->check(CLI::Range(0, 64));
  app.add_option("--times", opt.times_out, "append per-frame stage times as JSON lines");
  app.add_flag("-q,--quiet", opt.quiet, "print only the final JSON line");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  }

  pipeline::SegmenterParams params;
  try {
    config::DaemonConfig cfg;
    if (!opt.config_file.empty()) cfg = config::LoadConfig(opt.config_file);
    for (const std::string& o : opt.overrides) {
      config::ApplyOverride(o.rfind("segmenter.", 0) == 0 ? o : "segmenter." + o, &cfg);
    }
    cfg.segmenter.ValidateOrThrow();
    params = cfg.segmenter;
  } catch (const std::exception& e) {
    std::cerr << "clutterseg-segment: " << e.what() << "\n";
    return kExitUsage;
  }

  // Collect (input, output) pairs.
  struct Job {
    fs::path in, out, json, png;
  };
  std::vector<Job> jobs;
  std::error_code ec;
  const bool dir_mode = fs::is_directory(opt.input, ec);
  if (dir_mode) {
    std::vector<fs::path> inputs;
    // A directory of PCDs is read as such; otherwise its depth PNGs (names containing
    // "depth") are the frames.
    for (const auto& e : fs::directory_iterator(opt.input, ec)) {
      if (e.path().extension() == ".pcd") inputs.push_back(e.path());
    }
    if (inputs.empty()) {
      for (const auto& e : fs::directory_iterator(opt.input, ec)) {
        const fs::path& p = e.path();
        if (IsPng(p) && p.filename().string().find("depth") != std::string::npos) {
          inputs.push_back(p);
        }
      }
    }
    std::sort(inputs.begin(), inputs.end(), [](const fs::path& a, const fs::path& b) {
      return core::NaturalLess(a.filename().string(), b.filename().string());
    });
    if (inputs.empty()) {
      std::cerr << "clutterseg-segment: " << opt.input << ": no .pcd or .png files\n";
      return kExitData;
    }
    for (const std::string& d : {opt.output, opt.json_out, opt.png_out}) {
      if (!d.empty()) fs::create_directories(d, ec);
    }
    for (const fs::path& p : inputs) {
      const std::string stem = p.stem().string();
      Job j{p, fs::path(opt.output) / (stem + ".pcd"), {}, {}};
      if (!opt.json_out.empty()) j.json = fs::path(opt.json_out) / (stem + ".json");
      if (!opt.png_out.empty()) j.png = fs::path(opt.png_out) / (stem + ".png");
      jobs.push_back(j);
    }
  } else {
    if (!fs::exists(opt.input, ec)) {
      std::cerr << "clutterseg-segment: " << opt.input << ": no such file\n";
      return kExitData;
    }
    jobs.push_back(Job{opt.input, opt.output, opt.json_out, opt.png_out});
  }

  // Frames are segmented by `lanes` threads at once (each with its own Segmenter): loading,
  // segmenting and writing of one frame overlap with the others. Results
  // are reported in input order and do not depend on the number of lanes.
  core::ThreadPool pool(opt.threads);
  const int lanes =
      std::max(1, std::min(opt.lanes > 0 ? opt.lanes : std::min(pool.num_threads(), 2),
                           static_cast<int>(jobs.size())));
  struct Lane {
    explicit Lane(const pipeline::SegmenterParams& p, core::ThreadPool* pool)
        : segmenter(p, pool) {}
    pipeline::Segmenter segmenter;
    core::PointCloud cloud;
    pipeline::SegmentationResult result;
    core::ColorImage base, overlay;
  };
  std::vector<std::unique_ptr<Lane>> lane_state;
  // With several lanes every core already runs one: fanning out inside a frame as well would
  // only add threads (measured 10 % slower). The output is the same either way.
  for (int l = 0; l < lanes; ++l) {
    lane_state.push_back(std::make_unique<Lane>(params, lanes > 1 ? nullptr : &pool));
  }

  struct Report {
    bool done{false};
    bool failed{false};
    std::string message;     // progress line or error
    std::string times_line;  // --times JSON line
    double ms{0.0};
    size_t objects{0};
  };
  std::vector<Report> reports(jobs.size());
  std::mutex report_mutex;
  std::condition_variable report_cv;
  std::atomic<size_t> next_job{0};

  auto run_lane = [&](Lane* lane) {
    for (;;) {
      const size_t index = next_job.fetch_add(1);
      if (index >= jobs.size()) return;
      const Job& job = jobs[index];
      Report rep;
      try {
        core::CameraIntrinsics k;
        core::PointCloud& cloud = lane->cloud;
        LoadInput(job.in, opt, &cloud, &k);
        pipeline::SegmentationResult& result = lane->result;
        lane->segmenter.Process(cloud, k, &result);
        rep.ms = result.times.total_ms;
        rep.objects = result.objects.size();
        cloud.label = result.labels.data;
        io::WritePcd(job.out.string(), cloud, io::PcdEncoding::kBinary);
        if (!job.json.empty()) WriteObjectsJson(job.json.string(), job.in.string(), result);
        if (!job.png.empty()) {
          pipeline::CloudToImage(cloud, &lane->base);
          pipeline::RenderOverlay(result.labels, &lane->base, &lane->overlay);
          io::WriteColorPng(job.png.string(), lane->overlay);
        }
        const pipeline::StageTimes& t = result.times;
        core::JsonWriter j;
        j.BeginObject().Field("file", job.in.filename().string());
        j.Field("points_ms", t.points_ms).Field("voxelize_ms", t.voxelize_ms);
        j.Field("normals_ms", t.normals_ms).Field("supervoxels_ms", t.supervoxels_ms);
        j.Field("features_ms", t.features_ms).Field("linkage_ms", t.linkage_ms);
        j.Field("planes_ms", t.planes_ms).Field("objects_ms", t.objects_ms);
        j.Field("total_ms", t.total_ms).Field("objects", static_cast<uint64_t>(rep.objects));
        j.EndObject();
        rep.times_line = j.str();
        char line[512];
        std::snprintf(line, sizeof(line), "%s: %zu objects, %u supervoxels, %.1f ms",
                      job.in.filename().c_str(), result.objects.size(), result.num_supervoxels,
                      result.times.total_ms);
        rep.message = line;
      } catch (const std::exception& e) {
        rep.failed = true;
        rep.message = std::string("clutterseg-segment: ") + e.what();
      } catch (...) {
        rep.failed = true;
        rep.message = "clutterseg-segment: " + job.in.string() + ": unknown error";
      }
      rep.done = true;
      {
        std::lock_guard<std::mutex> lock(report_mutex);
        reports[index] = std::move(rep);
      }
      report_cv.notify_all();
    }
  };

  std::ofstream times;
  if (!opt.times_out.empty()) times.open(opt.times_out, std::ios::app);
  const auto wall_start = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (int l = 1; l < lanes; ++l) threads.emplace_back(run_lane, lane_state[l].get());
  // The main thread is lane 0 when there is one lane; otherwise it reports in order.
  if (lanes == 1)
    run_lane(lane_state[0].get());
  else
    threads.emplace_back(run_lane, lane_state[0].get());

  double total_ms = 0.0;
  size_t total_objects = 0;
  int failures = 0;
  for (size_t i = 0; i < jobs.size(); ++i) {
    Report rep;
    {
      std::unique_lock<std::mutex> lock(report_mutex);
      report_cv.wait(lock, [&] { return reports[i].done; });
      rep = std::move(reports[i]);
    }
    if (rep.failed) {
      std::cerr << rep.message << "\n";
      ++failures;
      continue;
    }
    total_ms += rep.ms;
    total_objects += rep.objects;
    if (times.is_open()) times << rep.times_line << "\n";
    if (!opt.quiet) std::fprintf(stderr, "%s\n", rep.message.c_str());
  }
  for (std::thread& t : threads) t.join();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();

  core::JsonWriter j;
  j.BeginObject().Field("frames", static_cast<uint64_t>(jobs.size()));
  j.Field("failed", failures).Field("objects", static_cast<uint64_t>(total_objects));
  // mean_ms: segmentation time of one frame (latency); wall_ms_per_frame: elapsed time of the
  // whole run, loading and writing included, divided by the frames (throughput).
  j.Field("mean_ms", jobs.size() == static_cast<size_t>(failures)
                         ? 0.0
                         : total_ms / static_cast<double>(jobs.size() - failures));
  j.Field("wall_ms_per_frame", jobs.empty() ? 0.0 : 1000.0 * wall_s / jobs.size());
  j.Field("threads", pool.num_threads()).Field("lanes", lanes).EndObject();
  std::cout << j.str() << std::endl;
  return failures == 0 ? kExitOk : kExitData;
}
