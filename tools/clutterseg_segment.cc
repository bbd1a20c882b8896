// clutterseg-segment: segments point clouds (PCD, organized or not) or depth PNGs into objects
// and writes a labelled PCD, the objects as JSON and an overlay PNG.
//
// Outputs are checked before anything is read: an output that is one of the inputs (the
// same file, also through a link), an output written twice, or (without --force) an existing
// output file is refused. Every write is checked (a full disk is an error; a partly written
// output is removed). An input that cannot be read is reported and counted and the others
// are still segmented. Exit codes (core/exit_codes.h): 0 every frame segmented and written;
// 5 finished, but some input could not be read or some output could not be written (each
// named on stderr, counted in the summary); 1 no input could be read, or no frame had a
// valid point; 2 bad command line or refused outputs; 3 the input does not exist.

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "clutterseg/config/segmenter_keys.h"
#include "clutterseg/core/exit_codes.h"
#include "clutterseg/core/text_and_color.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/pipeline/frame_runner.h"
#include "clutterseg/pipeline/overlay.h"
#include "clutterseg/pipeline/segmenter.h"

namespace fs = std::filesystem;
using namespace clutterseg;
// Keys in the order they are set, as the JSON outputs have always listed them.
using Json = nlohmann::ordered_json;

namespace {

struct Options {
  std::string input;
  std::string output;
  std::string config_file;
  std::vector<std::string> overrides;
  std::string json_out;
  std::string png_out;
  std::string intrinsics_file;
  // --intrinsics, read once before any frame (a bad file is a usage error, exit 2); unset:
  // DefaultKinectIntrinsics().
  std::optional<core::CameraIntrinsics> intrinsics;
  std::string color_png;
  std::string times_out;
  double depth_scale_to_mm{1.0};
  int threads{0};
  int lanes{0};
  int png_scale{1};
  bool quiet{false};
  bool force{false};
};

// `in` made `factor` times smaller in each direction, each pixel the mean of its factor x factor
// block (a partial block at the right or bottom edge is averaged over the pixels it has).
void Shrink(const core::ColorImage& in, int factor, core::ColorImage* out) {
  const int w = (in.width + factor - 1) / factor, h = (in.height + factor - 1) / factor;
  out->Reset(w, h);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      unsigned r = 0, g = 0, b = 0, n = 0;
      for (int y = v * factor; y < std::min(in.height, (v + 1) * factor); ++y) {
        for (int x = u * factor; x < std::min(in.width, (u + 1) * factor); ++x) {
          const core::Rgb8& c = in.at(x, y);
          r += c.r;
          g += c.g;
          b += c.b;
          ++n;
        }
      }
      out->at(u, v) =
          core::Rgb8{static_cast<uint8_t>((r + n / 2) / n), static_cast<uint8_t>((g + n / 2) / n),
                     static_cast<uint8_t>((b + n / 2) / n)};
    }
  }
}

// Writes `text` to `path` (created or truncated), checking every write and the close.
void WriteTextFile(const std::string& path, const std::string& text) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error(path + ": cannot open for writing: " + std::strerror(errno));
  const char* p = text.data();
  size_t left = text.size();
  while (left > 0) {
    const ssize_t w = ::write(fd, p, left);
    if (w < 0) {
      if (errno == EINTR) continue;
      const std::string why = std::strerror(errno);
      ::close(fd);
      throw std::runtime_error(path + ": write failed: " + why);
    }
    p += w;
    left -= static_cast<size_t>(w);
  }
  if (::close(fd) != 0) {
    throw std::runtime_error(path + ": write failed on close: " + std::strerror(errno));
  }
}

// One line of compact JSON. A non-finite number is written as null; bytes of a string that are
// not UTF-8 (a file name may hold any) as U+FFFD, so that the text is always valid JSON.
std::string JsonLine(const Json& j) {
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

Json Vec(const core::Vec3f& v) { return Json::array({v.x, v.y, v.z}); }

// Every stage of pipeline::StageTable() and the total, as fields "<name><suffix>".
void AddStageTimes(const pipeline::StageTimes& t, const std::string& suffix, Json* j) {
  for (size_t i = 0; i < pipeline::kNumStages; ++i) {
    (*j)[std::string(pipeline::StageTable()[i].name) + suffix] = t.ms[i];
  }
  (*j)["total" + suffix] = t.total_ms;
}

void WriteObjectsJson(const std::string& path, const std::string& source,
                      const pipeline::SegmentationResult& r) {
  Json planes = Json::array();
  for (const pipeline::Plane& p : r.planes) {
    planes.push_back({{"id", p.id},
                      {"normal", Vec(p.normal)},
                      {"d", p.d},
                      {"num_points", p.num_points},
                      {"is_support", p.is_support}});
  }
  Json objects = Json::array();
  for (const pipeline::Object& o : r.objects) {
    objects.push_back(
        {{"id", o.id},
         {"num_points", o.num_points},
         {"centroid", Vec(o.centroid)},
         {"aabb_min", Vec(o.aabb_min)},
         {"aabb_max", Vec(o.aabb_max)},
         {"obb_center", Vec(o.obb_center)},
         {"obb_axes", {Vec(o.obb_axes[0]), Vec(o.obb_axes[1]), Vec(o.obb_axes[2])}},
         {"obb_extents", Vec(o.obb_extents)},
         {"support_plane_id", o.support_plane_id},
         {"mean_color", {o.mean_color.r, o.mean_color.g, o.mean_color.b}},
         {"confidence", o.confidence},
         {"pixel_bbox", {o.pixel_min_u, o.pixel_min_v, o.pixel_max_u, o.pixel_max_v}}});
  }
  Json times = Json::object();
  AddStageTimes(r.times, "", &times);
  const Json j = {{"source", source},
                  {"width", r.width},
                  {"height", r.height},
                  {"num_valid_points", r.num_valid_points},
                  {"num_supervoxels", r.num_supervoxels},
                  {"planes", std::move(planes)},
                  {"objects", std::move(objects)},
                  {"times_ms", std::move(times)}};
  WriteTextFile(path, JsonLine(j) + "\n");
}

bool IsPng(const fs::path& p) { return core::HasExtension(p.filename().string(), ".png"); }

// Loads `in` into `cloud`, reusing its storage (a PCD after another allocates nothing).
void LoadInput(const fs::path& in, const Options& opt, core::PointCloud* cloud,
               core::CameraIntrinsics* intrinsics) {
  if (IsPng(in)) {
    *intrinsics = opt.intrinsics.value_or(core::DefaultKinectIntrinsics());
    *cloud = io::ReadDepthPngCloud(in.string(), *intrinsics, opt.color_png, opt.depth_scale_to_mm,
                                   core::FrameLimits{});
    return;
  }
  // Organized or not (HEIGHT 1): the labels follow the input's points either way. The
  // intrinsics are used for an organized cloud, and to draw an unorganized one (--png).
  io::ReadPcd(in.string(), io::ReadLimits{}, cloud);
  *intrinsics =
      core::IntrinsicsForCloud(opt.intrinsics.value_or(core::DefaultKinectIntrinsics()), *cloud);
}

// One file the run reads or writes, for the checks before it starts.
struct FileUse {
  fs::path path;
  std::string role;  // e.g. "input", "labelled cloud of a.pcd"
};

// The same file: equal paths after resolving links and "..", or the same inode.
bool SameFile(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  const fs::path ca = fs::weakly_canonical(a, ec);
  const fs::path cb = fs::weakly_canonical(b, ec);
  if (!ca.empty() && ca == cb) return true;
  return fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec);
}

// Refuses outputs that are inputs, outputs written twice and (without `force`) existing
// output files; `appended` outputs (--times) may exist. Returns the problem, "" when none.
std::string CheckOutputs(const std::vector<FileUse>& inputs, const std::vector<FileUse>& outputs,
                         const std::vector<bool>& appended, bool force) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const FileUse& out = outputs[i];
    for (const FileUse& in : inputs) {
      if (SameFile(out.path, in.path)) {
        return "the " + out.role + " '" + out.path.string() + "' is the " + in.role + " '" +
               in.path.string() + "': refusing to overwrite an input";
      }
    }
    for (size_t k = 0; k < i; ++k) {
      if (SameFile(out.path, outputs[k].path)) {
        return "'" + out.path.string() + "' would be written twice, as the " + outputs[k].role +
               " and as the " + out.role;
      }
    }
    std::error_code ec;
    const fs::file_status st = fs::status(out.path, ec);
    if (fs::is_directory(st)) {
      return "the " + out.role + " '" + out.path.string() + "' is a directory";
    }
    if (fs::is_regular_file(st) && !force && !appended[i]) {
      return "the " + out.role + " '" + out.path.string() +
             "' exists; use --force to overwrite existing outputs";
    }
  }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  CLI::App app{
      "Segments a point cloud (PCD, organized or not) or a depth PNG into objects.\n"
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
  app.add_option("--png", opt.png_out,
                 "write an overlay PNG of the objects (an unorganized cloud is drawn through "
                 "the intrinsics)");
  app.add_option("--png-scale", opt.png_scale,
                 "write the overlay PNG this many times smaller in each direction (block mean)")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
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
  app.add_flag("--force", opt.force, "overwrite existing output files");
  app.add_flag("-q,--quiet", opt.quiet, "print only the final JSON line");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  }

  pipeline::SegmenterParams params;
  try {
    if (!opt.config_file.empty()) config::LoadSegmenterParams(opt.config_file, &params);
    for (const std::string& o : opt.overrides) config::ApplySegmenterOverride(o, &params);
    params.ValidateOrThrow();
  } catch (const std::exception& e) {
    std::cerr << "clutterseg-segment: " << e.what() << "\n";
    return kExitUsage;
  }
  // The --intrinsics file is configuration, as camera.intrinsics_file is for the daemon: a
  // missing or bad one is a usage error (exit 2) named once, not a failure of every frame.
  if (!opt.intrinsics_file.empty()) {
    try {
      opt.intrinsics = io::ReadIntrinsicsJson(opt.intrinsics_file);
    } catch (const std::exception& e) {
      std::cerr << "clutterseg-segment: --intrinsics: " << e.what() << "\n";
      return kExitUsage;
    }
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
      if (core::HasExtension(e.path().filename().string(), ".pcd")) inputs.push_back(e.path());
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
      std::cerr << "clutterseg-segment: " << opt.input
                << ": no .pcd files and no depth PNGs (*.png with 'depth' in the name)\n";
      return kExitSourceUnavailable;
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
      return kExitSourceUnavailable;
    }
    jobs.push_back(Job{opt.input, opt.output, opt.json_out, opt.png_out});
  }

  // Nothing is written over an input, twice, or (without --force) over an existing file.
  {
    std::vector<FileUse> inputs;
    std::vector<FileUse> outputs;
    std::vector<bool> appended;
    for (const Job& job : jobs) inputs.push_back({job.in, "input"});
    if (!opt.intrinsics_file.empty()) inputs.push_back({opt.intrinsics_file, "--intrinsics file"});
    if (!opt.color_png.empty()) inputs.push_back({opt.color_png, "--color input"});
    if (!opt.config_file.empty()) inputs.push_back({opt.config_file, "--config file"});
    for (const Job& job : jobs) {
      const std::string of = job.in.filename().string();
      outputs.push_back({job.out, "labelled cloud of " + of});
      appended.push_back(false);
      if (!job.json.empty()) {
        outputs.push_back({job.json, "JSON of " + of});
        appended.push_back(false);
      }
      if (!job.png.empty()) {
        outputs.push_back({job.png, "overlay PNG of " + of});
        appended.push_back(false);
      }
    }
    if (!opt.times_out.empty()) {
      outputs.push_back({opt.times_out, "--times file"});
      appended.push_back(true);
    }
    const std::string problem = CheckOutputs(inputs, outputs, appended, opt.force);
    if (!problem.empty()) {
      std::cerr << "clutterseg-segment: " << problem << "\n";
      return kExitUsage;
    }
  }
  if (dir_mode) {
    for (const std::string& d : {opt.output, opt.json_out, opt.png_out}) {
      if (d.empty()) continue;
      fs::create_directories(d, ec);
      if (!fs::is_directory(d)) {
        std::cerr << "clutterseg-segment: cannot create the output directory '" << d
                  << "': " << (ec ? ec.message() : std::string("not a directory")) << "\n";
        return kExitFailure;
      }
    }
  }

  // Frames are segmented on `lanes` lanes at once (pipeline::FrameRunner, each lane with its
  // own Segmenter): loading, segmenting and writing of one frame overlap with the others.
  // Results are reported in input order and do not depend on the number of lanes.
  pipeline::FrameRunnerParams runner_params;
  runner_params.threads = opt.threads;
  runner_params.policy = pipeline::DispatchPolicy::kThroughput;
  {
    const int cores = opt.threads > 0
                          ? opt.threads
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    runner_params.pipeline_depth = std::max(
        1, std::min(opt.lanes > 0 ? opt.lanes : std::min(cores, 2), static_cast<int>(jobs.size())));
  }
  // Per-lane buffers (index = lane): a PCD after another allocates nothing.
  struct LaneBuffers {
    core::PointCloud cloud, view;
    core::LabelImage view_labels;
    core::ColorImage base, overlay, small;
    std::string message;       // progress line or error
    std::string times_line;    // --times JSON line
    bool write_failed{false};  // the frame failed writing its outputs (not reading its input)
  };
  std::vector<LaneBuffers> buffers(static_cast<size_t>(runner_params.pipeline_depth));

  std::FILE* times = nullptr;
  if (!opt.times_out.empty()) {
    times = std::fopen(opt.times_out.c_str(), "a");
    if (times == nullptr) {
      std::cerr << "clutterseg-segment: " << opt.times_out
                << ": cannot open for appending: " << std::strerror(errno) << "\n";
      return kExitFailure;
    }
  }
  bool times_failed = false;
  double total_ms = 0.0;
  size_t total_objects = 0;
  int failures = 0;        // frames that failed, for any reason
  int write_failures = 0;  // of which because an output could not be written
  int empty_frames = 0;    // segmented, but no valid point in the depth range
  auto work = [&](const pipeline::FrameRunner::Lane& lane, uint64_t index) {
    const Job& job = jobs[index];
    LaneBuffers& b = buffers[static_cast<size_t>(lane.index)];
    b.write_failed = false;
    core::CameraIntrinsics k;
    LoadInput(job.in, opt, &b.cloud, &k);
    pipeline::SegmentationResult& result = *lane.result;
    lane.segmenter->Process(b.cloud, k, &result);
    b.cloud.label = result.labels.data;
    try {
      io::WritePcd(job.out.string(), b.cloud, io::PcdEncoding::kBinary);
      if (!job.json.empty()) WriteObjectsJson(job.json.string(), job.in.string(), result);
      if (!job.png.empty()) {
        if (b.cloud.organized()) {
          pipeline::CloudToImage(b.cloud, &b.base);
          pipeline::RenderOverlay(result.labels, &b.base, &b.overlay);
        } else {  // drawn through the intrinsics, for display only
          pipeline::ProjectForDisplay(b.cloud, result.labels, k, &b.view, &b.view_labels);
          pipeline::CloudToImage(b.view, &b.base);
          pipeline::RenderOverlay(b.view_labels, &b.base, &b.overlay);
        }
        if (opt.png_scale > 1) {
          Shrink(b.overlay, opt.png_scale, &b.small);
          io::WriteColorPng(job.png.string(), b.small);
        } else {
          io::WriteColorPng(job.png.string(), b.overlay);
        }
      }
    } catch (...) {
      b.write_failed = true;
      // No partly written output may look like a result.
      std::error_code remove_ec;
      for (const fs::path& p : {job.out, job.json, job.png}) {
        if (!p.empty() && fs::is_regular_file(p, remove_ec)) fs::remove(p, remove_ec);
      }
      throw;
    }
    Json j = {{"file", job.in.filename().string()}};
    AddStageTimes(result.times, "_ms", &j);
    j["objects"] = result.objects.size();
    b.times_line = JsonLine(j);
    char line[512];
    std::snprintf(line, sizeof(line), "%s: %zu objects, %u supervoxels, %.1f ms",
                  job.in.filename().c_str(), result.objects.size(), result.num_supervoxels,
                  result.times.total_ms);
    b.message = line;
  };
  // In input order, on one lane thread at a time.
  auto done = [&](const pipeline::FrameRunner::Lane& lane, uint64_t index,
                  const std::string* error) {
    if (error != nullptr) {
      const std::string in = jobs[index].in.string();
      std::cerr << "clutterseg-segment: "
                << (error->find(in) == std::string::npos ? in + ": " : std::string()) << *error
                << "\n";
      ++failures;
      write_failures += buffers[static_cast<size_t>(lane.index)].write_failed ? 1 : 0;
      return;
    }
    const LaneBuffers& b = buffers[static_cast<size_t>(lane.index)];
    total_ms += lane.result->times.total_ms;
    total_objects += lane.result->objects.size();
    if (lane.result->num_valid_points == 0) {
      ++empty_frames;
      std::cerr << "clutterseg-segment: " << jobs[index].in.string()
                << ": no valid point in the depth range " << params.points.min_depth_m << ".."
                << params.points.max_depth_m << " m\n";
    }
    if (times != nullptr && !times_failed &&
        std::fprintf(times, "%s\n", b.times_line.c_str()) < 0) {
      times_failed = true;
    }
    if (!opt.quiet) std::fprintf(stderr, "%s\n", b.message.c_str());
  };
  const auto wall_start = std::chrono::steady_clock::now();
  int threads_used = 1;
  {
    pipeline::FrameRunner runner(params, runner_params, work, done);
    threads_used = runner.pool() != nullptr ? runner.pool()->num_threads() : 1;
    for (size_t i = 0; i < jobs.size(); ++i) runner.Submit(i);
    runner.Drain();
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const int lanes = runner_params.pipeline_depth;
  if (times != nullptr) {
    const bool flushed = std::fflush(times) == 0 && std::ferror(times) == 0;
    const int saved_errno = errno;
    if (std::fclose(times) != 0 || !flushed || times_failed) {
      std::cerr << "clutterseg-segment: " << opt.times_out
                << ": write failed: " << std::strerror(saved_errno != 0 ? saved_errno : errno)
                << "\n";
      times_failed = true;
    }
  }
  const int segmented = static_cast<int>(jobs.size()) - failures;
  const int unreadable = failures - write_failures;
  const bool all_empty = segmented > 0 && empty_frames == segmented;
  if (failures > 0) {
    std::cerr << "clutterseg-segment: " << failures << " of " << jobs.size()
              << " frame(s) failed\n";
  }
  if (all_empty) {
    std::cerr << "clutterseg-segment: every frame had no valid point in the depth range "
              << params.points.min_depth_m << ".." << params.points.max_depth_m
              << " m: check the input's depth unit (--depth-scale; TUM PNGs need 0.2) and "
                 "segmenter.points\n";
  }

  // mean_ms: segmentation time of one frame (latency); wall_ms_per_frame: elapsed time of the
  // whole run, loading and writing included, divided by the frames (throughput).
  const Json j = {{"frames", jobs.size()},
                  {"failed", failures},
                  {"empty", empty_frames},
                  {"objects", total_objects},
                  {"mean_ms", jobs.size() == static_cast<size_t>(failures)
                                  ? 0.0
                                  : total_ms / static_cast<double>(jobs.size() - failures)},
                  {"wall_ms_per_frame", jobs.empty() ? 0.0 : 1000.0 * wall_s / jobs.size()},
                  {"threads", threads_used},
                  {"lanes", lanes}};
  errno = 0;
  std::cout << JsonLine(j) << std::endl;
  const bool summary_written = static_cast<bool>(std::cout);
  if (!summary_written) {
    std::cerr << "clutterseg-segment: cannot write the summary to standard output: "
              << std::strerror(errno != 0 ? errno : EIO) << "\n";
  }
  if (unreadable == static_cast<int>(jobs.size()) || all_empty) return kExitFailure;
  if (failures > 0 || times_failed || !summary_written) return kExitIncomplete;
  return kExitOk;
}
