// clutterseg-bench: per-stage timings, single-segmenter and pipelined throughput, peak RSS
// and steady-state heap allocations of the Segmenter, optionally against PCL's supervoxels +
// LCCP on the same frames in the same run.

#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <sys/resource.h>

#include "clutterseg/config/key_table.h"
#include "clutterseg/config/segmenter_keys.h"
#include "clutterseg/core/exit_codes.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/frame_runner.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/pipeline/segmenter_params.h"
#include "clutterseg/version.h"
#include "tools/bench/alloc_counter.h"
#include "tools/bench/frame_set.h"
#if CLUTTERSEG_BENCH_HAVE_PCL
#include "tools/bench/pcl_lccp_runner.h"
#endif

namespace clutterseg::bench {
namespace {

using Clock = std::chrono::steady_clock;

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

double ProcessCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

// ---------------------------------------------------------------------------------------
// Statistics.

struct Summary {
  double mean{0}, p50{0}, p90{0}, p99{0}, max{0};
};

// Percentiles by linear interpolation between closest ranks.
Summary Summarize(std::vector<double> v) {
  Summary s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  double sum = 0;
  for (double x : v) sum += x;
  s.mean = sum / static_cast<double>(v.size());
  auto pct = [&v](double q) {
    const double pos = q * static_cast<double>(v.size() - 1);
    const size_t lo = static_cast<size_t>(std::floor(pos));
    const size_t hi = std::min(v.size() - 1, lo + 1);
    return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
  };
  s.p50 = pct(0.5);
  s.p90 = pct(0.9);
  s.p99 = pct(0.99);
  s.max = v.back();
  return s;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The reported stages: pipeline::StageTable() in order, then the whole Process call.
struct StageDef {
  std::string name;
  double (*get)(const pipeline::StageTimes&, size_t);
  size_t index;
};

const std::vector<StageDef>& Stages() {
  static const std::vector<StageDef> kStages = [] {
    std::vector<StageDef> s;
    for (size_t i = 0; i < pipeline::kNumStages; ++i) {
      s.push_back({std::string(pipeline::StageTable()[i].name),
                   [](const pipeline::StageTimes& t, size_t k) { return t.ms[k]; }, i});
    }
    s.push_back({"total", [](const pipeline::StageTimes& t, size_t) { return t.total_ms; }, 0});
    return s;
  }();
  return kStages;
}

// ---------------------------------------------------------------------------------------
// Memory.

struct ProcStatus {
  double vm_rss_mb{0};
  double vm_hwm_mb{0};
};

ProcStatus ReadProcStatus() {
  ProcStatus s;
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    double kb = 0;
    if (std::sscanf(line.c_str(), "VmRSS: %lf kB", &kb) == 1) s.vm_rss_mb = kb / 1024.0;
    if (std::sscanf(line.c_str(), "VmHWM: %lf kB", &kb) == 1) s.vm_hwm_mb = kb / 1024.0;
  }
  return s;
}

double MaxRssMb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;  // kilobytes on Linux
}

// Resets VmHWM to the current RSS (Linux >= 4.0); false when not permitted.
bool ResetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  if (!out) return false;
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  double a = 0, b = 0, c = 0;
  in >> a >> b >> c;
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.2f %.2f %.2f", a, b, c);
  return buf;
}

// ---------------------------------------------------------------------------------------
// Runs.

// How the frames are run: pipeline::FrameRunner with `lanes` Segmenters sharing a pool of
// `pool_threads` (1 = no pool), as the daemon and clutterseg-segment run them.
struct Config {
  std::string name;
  int lanes{1};
  int pool_threads{1};
};

struct Sample {
  pipeline::StageTimes times;
  double wall_ms{0};
  uint32_t supervoxels{0};
  uint32_t objects{0};
  uint32_t valid_points{0};
  uint32_t support_first_points{0};
};

struct ConfigResult {
  Config config;
  size_t frames{0};  // processed in the timed passes
  double wall_ms{0};
  double cpu_ms{0};
  AllocCounts allocs;
  double fps{0};
  double cpu_ms_per_frame{0};
  std::vector<Summary> stages;  // per Stages() entry, over frames (median over repetitions)
  Summary latency;              // Process() wall time per frame, over frames
  double supervoxels_mean{0};
  double objects_mean{0};
  double valid_points_mean{0};
  double support_first_points_mean{0};
  double rss_before_mb{0};  // VmRSS before the configuration's segmenters were created
  double peak_rss_mb{0};    // VmHWM during the configuration (reset before it when possible)
};

ConfigResult RunConfig(const FrameSet& frames, const pipeline::SegmenterParams& params,
                       const Config& config, int repeat, int warmup, int trace_allocs) {
  const size_t n = frames.size();
  ResetPeakRss();
  const double rss_before = ReadProcStatus().vm_rss_mb;
  const size_t total = n * static_cast<size_t>(repeat);
  std::vector<Sample> samples(total);
  bool record = false;
  // Jobs are frame indices modulo n (timed jobs 0..total-1), taken by whichever lane is free.
  auto work = [&](const pipeline::FrameRunner::Lane& lane, uint64_t job) {
    const size_t f = job % n;
    const Clock::time_point t0 = Clock::now();
    lane.segmenter->Process(frames.clouds[f], frames.intrinsics, lane.result);
    const Clock::time_point t1 = Clock::now();
    if (record) {
      Sample& s = samples[job];
      s.times = lane.result->times;
      s.wall_ms = MsBetween(t0, t1);
      s.supervoxels = lane.result->num_supervoxels;
      s.objects = static_cast<uint32_t>(lane.result->objects.size());
      s.valid_points = lane.result->num_valid_points;
      s.support_first_points = lane.result->num_support_first_points;
    }
  };
  std::string error;
  auto done = [&](const pipeline::FrameRunner::Lane&, uint64_t, const std::string* e) {
    if (e != nullptr && error.empty()) error = *e;
  };
  pipeline::FrameRunnerParams rp;
  rp.pipeline_depth = config.lanes;
  rp.threads = config.pool_threads;
  rp.policy = pipeline::DispatchPolicy::kThroughput;
  pipeline::FrameRunner runner(params, rp, work, done);
  // Warm-up: every lane's Segmenter processes every frame, so that its buffers have grown to
  // the largest frame before the timed loop.
  for (int w = 0; w < warmup; ++w) {
    runner.ForEachLane([&](const pipeline::FrameRunner::Lane& lane) {
      const core::ThreadPool::ActiveCaller active(runner.pool());
      for (size_t f = 0; f < n; ++f) {
        lane.segmenter->Process(frames.clouds[f], frames.intrinsics, lane.result);
      }
    });
  }
  TraceNextAllocations(trace_allocs);
  record = true;
  const AllocCounts a0 = CurrentAllocCounts();
  const double cpu0 = ProcessCpuMs();
  const Clock::time_point t0 = Clock::now();
  for (size_t j = 0; j < total; ++j) runner.Submit(j);
  runner.Drain();
  const Clock::time_point t1 = Clock::now();
  const double cpu1 = ProcessCpuMs();
  const AllocCounts a1 = CurrentAllocCounts();
  TraceNextAllocations(0);
  if (!error.empty()) throw std::runtime_error(error);

  ConfigResult r;
  r.config = config;
  r.wall_ms = MsBetween(t0, t1);
  r.cpu_ms = cpu1 - cpu0;
  r.allocs = a1 - a0;
  r.rss_before_mb = rss_before;
  r.peak_rss_mb = ReadProcStatus().vm_hwm_mb;
  r.frames = total;
  r.fps = r.wall_ms > 0 ? 1000.0 * static_cast<double>(total) / r.wall_ms : 0.0;
  r.cpu_ms_per_frame = r.cpu_ms / static_cast<double>(total);

  // Per frame: median over repetitions; then statistics over frames.
  const auto& stages = Stages();
  std::vector<double> per_frame(n), reps(static_cast<size_t>(repeat));
  for (const StageDef& s : stages) {
    for (size_t f = 0; f < n; ++f) {
      for (int k = 0; k < repeat; ++k) reps[k] = s.get(samples[k * n + f].times, s.index);
      per_frame[f] = Median(reps);
    }
    r.stages.push_back(Summarize(per_frame));
  }
  for (size_t f = 0; f < n; ++f) {
    for (int k = 0; k < repeat; ++k) reps[k] = samples[k * n + f].wall_ms;
    per_frame[f] = Median(reps);
  }
  r.latency = Summarize(per_frame);
  uint64_t sv_sum = 0, obj_sum = 0, valid_sum = 0, taken_sum = 0;
  for (size_t f = 0; f < n; ++f) {  // first repetition
    sv_sum += samples[f].supervoxels;
    obj_sum += samples[f].objects;
    valid_sum += samples[f].valid_points;
    taken_sum += samples[f].support_first_points;
  }
  r.valid_points_mean = static_cast<double>(valid_sum) / static_cast<double>(n);
  r.support_first_points_mean = static_cast<double>(taken_sum) / static_cast<double>(n);
  r.supervoxels_mean = static_cast<double>(sv_sum) / static_cast<double>(n);
  r.objects_mean = static_cast<double>(obj_sum) / static_cast<double>(n);
  return r;
}

#if CLUTTERSEG_BENCH_HAVE_PCL
double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

struct PclResult {
  Summary supervoxels, lccp, total;
  double cpu_ms_per_frame{0};  // thread CPU time of the runs, mean per run
  double supervoxels_mean_count{0};
  double segments_mean{0};
  double peak_rss_mb{0};
};

PclResult RunPcl(const FrameSet& frames, const pcl_baseline::BaselineParams& params, int repeat) {
  PclLccpRunner runner{params};
  std::vector<double> sv(frames.size()), lc(frames.size()), tot(frames.size());
  std::vector<double> rs(static_cast<size_t>(repeat)), rl(rs.size()), rt(rs.size());
  PclResult out;
  for (size_t f = 0; f < frames.size(); ++f) {
    runner.SetInput(frames.clouds[f]);
    for (int k = 0; k < repeat; ++k) {
      const double cpu0 = ThreadCpuMs();
      const PclLccpTimes t = runner.Run();
      out.cpu_ms_per_frame += ThreadCpuMs() - cpu0;
      rs[k] = t.supervoxels_ms;
      rl[k] = t.lccp_ms;
      rt[k] = t.total_ms;
      if (k == 0) {
        out.supervoxels_mean_count += static_cast<double>(t.num_supervoxels);
        out.segments_mean += static_cast<double>(t.num_segments);
      }
    }
    sv[f] = Median(rs);
    lc[f] = Median(rl);
    tot[f] = Median(rt);
  }
  out.supervoxels = Summarize(sv);
  out.lccp = Summarize(lc);
  out.total = Summarize(tot);
  out.supervoxels_mean_count /= static_cast<double>(frames.size());
  out.cpu_ms_per_frame /= static_cast<double>(frames.size()) * repeat;
  out.segments_mean /= static_cast<double>(frames.size());
  return out;
}
#endif

// ---------------------------------------------------------------------------------------
// Output.

// Keys in the order they are set, as the summary has always listed them.
using Json = nlohmann::ordered_json;

Json SummaryJson(const Summary& s) {
  return {{"mean", s.mean}, {"p50", s.p50}, {"p90", s.p90}, {"p99", s.p99}, {"max", s.max}};
}

void PrintStageTable(const ConfigResult& r, const char* what = "") {
  std::printf(
      "\nPer-stage wall time, ms (%s%s; per frame the median of the repetitions,\n"
      "then statistics over frames):\n",
      r.config.name.c_str(), what);
  std::printf("  %-18s %9s %9s %9s %9s %9s\n", "stage", "mean", "p50", "p90", "p99", "max");
  const auto& stages = Stages();
  for (size_t i = 0; i < stages.size(); ++i) {
    const Summary& s = r.stages[i];
    std::printf("  %-18s %9.2f %9.2f %9.2f %9.2f %9.2f\n", stages[i].name.c_str(), s.mean, s.p50,
                s.p90, s.p99, s.max);
  }
  const Summary& l = r.latency;
  std::printf("  %-18s %9.2f %9.2f %9.2f %9.2f %9.2f\n", "end-to-end (wall)", l.mean, l.p50, l.p90,
              l.p99, l.max);
}

struct Options {
  std::string dir;
  int synthetic{0};
  uint64_t seed{7};
  size_t max_frames{0};
  int repeat{3};
  int warmup{1};
  int threads{0};
  bool pipelined{true};
  bool unorganized{true};
  bool pcl{false};
  int pcl_repeat{1};
  bool pcl_single_camera_transform{false};
  bool pcl_no_extended{false};
  std::string json_path;
  int trace_allocs{0};
  size_t trace_config{0};
  std::vector<std::string> overrides;
};

int Run(int argc, char** argv) {
  Options opt;
  CLI::App app{
      "Benchmarks the clutterseg Segmenter on a directory of PCD frames or on synthetic "
      "renders: per-stage wall times, frames per second for one segmenter and for two "
      "pipelined segmenters, peak RSS and heap allocations per frame at steady state."};
  app.add_option("DIR", opt.dir, "directory of *.pcd frames (organized or not)");
  app.add_option("--synthetic", opt.synthetic, "render N synthetic frames instead of DIR")
      ->check(CLI::Range(1, 100000));
  app.add_option("--seed", opt.seed, "synthetic seed (frames equal clutterseg-synth --seed)")
      ->capture_default_str();
  app.add_option("--max-frames", opt.max_frames, "use at most N frames of DIR (0 = all)");
  app.add_option("--repeat,-r", opt.repeat, "timed passes over the frames")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--warmup", opt.warmup, "untimed passes before each measurement")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  app.add_option("--threads,-t", opt.threads, "threads of the segmenter's pool (0 = cores)")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  app.add_flag("!--no-pipelined", opt.pipelined, "skip the two-segmenter configurations");
  app.add_flag("!--no-unorganized", opt.unorganized,
               "skip the run of the same frames as shuffled unorganized clouds (HEIGHT 1)");
  app.add_flag("--pcl", opt.pcl, "also run PCL supervoxels + LCCP on the same frames");
  app.add_option("--pcl-repeat", opt.pcl_repeat, "PCL runs per frame (median is used)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_flag("--pcl-single-camera-transform", opt.pcl_single_camera_transform,
               "PCL voxelizes in the depth-dependent space (clutterseg-pcl-baseline's flag of "
               "the same name)");
  app.add_flag("--pcl-no-extended", opt.pcl_no_extended,
               "PCL's LCCP without extended convexity (clutterseg-pcl-baseline --no-extended); "
               "with --pcl-single-camera-transform PCL's best quality on the mOSD frames");
  app.add_option("--trace-allocs", opt.trace_allocs,
                 "print the call stacks of the first N allocations in a timed loop")
      ->check(CLI::Range(0, 100000));
  app.add_option("--trace-config", opt.trace_config,
                 "configuration (0-based, in the throughput table's order) to trace")
      ->capture_default_str();
  app.add_option("--set", opt.overrides,
                 "segmenter parameter KEY=VALUE (keys of the configuration's segmenter "
                 "section, e.g. supervoxel.refinement_iterations=0); repeatable");
  app.add_option("--json", opt.json_path, "also write the JSON summary line to this file");
  app.set_version_flag("--version", std::string("clutterseg-bench ") + clutterseg::kVersion);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  }
  if (opt.dir.empty() == (opt.synthetic == 0)) {
    throw std::invalid_argument("give either DIR or --synthetic N (not both)");
  }
  if (!opt.pcl && (opt.pcl_single_camera_transform || opt.pcl_no_extended)) {
    throw std::invalid_argument("--pcl-single-camera-transform and --pcl-no-extended need --pcl");
  }
#if !CLUTTERSEG_BENCH_HAVE_PCL
  if (opt.pcl) {
    throw std::invalid_argument(
        "--pcl needs a build with -DCLUTTERSEG_PCL_BASELINE=ON (PCL is not linked)");
  }
#endif
  const int threads = opt.threads > 0
                          ? opt.threads
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const std::string load_start = LoadAverage();

  const Clock::time_point tl = Clock::now();
  const FrameSet frames = opt.synthetic > 0
                              ? RenderSyntheticFrames(opt.synthetic, opt.seed, threads)
                              : LoadPcdDirectory(opt.dir, opt.max_frames);
  const double load_ms = MsBetween(tl, Clock::now());
  size_t valid_points = 0;
  for (const auto& c : frames.clouds) valid_points += c.CountValid();
  const double frames_mb = static_cast<double>(frames.HeapBytes()) / (1024.0 * 1024.0);
  std::printf(
      "clutterseg-bench: %zu frames from %s (%.0f ms to load, %.1f MiB in memory, "
      "%.0f valid points per frame)\n",
      frames.size(), frames.source.c_str(), load_ms, frames_mb,
      static_cast<double>(valid_points) / static_cast<double>(frames.size()));
  std::printf("threads %d, repetitions %d, warm-up passes %d, load average at start %s\n", threads,
              opt.repeat, opt.warmup, load_start.c_str());

  pipeline::SegmenterParams params;
  for (const std::string& o : opt.overrides) {
    try {
      config::ApplySegmenterOverride(o, &params);
    } catch (const config::ConfigError& e) {  // an unknown key or bad value: usage, exit 2
      throw std::invalid_argument(std::string("--set ") + e.what());
    }
    std::printf("segmenter parameter %s\n", o.c_str());
  }
  params.ValidateOrThrow();
  const ProcStatus after_load = ReadProcStatus();
  const bool hwm_reset = ResetPeakRss();

  std::vector<Config> configs;
  configs.push_back({"1 lane, pool " + std::to_string(threads), 1, threads});
  if (threads > 1) configs.push_back({"1 lane, no pool", 1, 1});
  if (opt.pipelined) {
    configs.push_back({"2 lanes, shared pool " + std::to_string(threads), 2, threads});
    configs.push_back({"2 lanes, no pool", 2, 1});
  }
  std::vector<ConfigResult> results;
  for (size_t i = 0; i < configs.size(); ++i) {
    std::fprintf(stderr, "running: %s\n", configs[i].name.c_str());
    results.push_back(RunConfig(frames, params, configs[i], opt.repeat, opt.warmup,
                                i == opt.trace_config ? opt.trace_allocs : 0));
  }
  // The same frames without their image grid: the valid points shuffled into one row.
  FrameSet unorganized_frames;
  std::vector<ConfigResult> unorganized;
  if (opt.unorganized) {
    unorganized_frames = ShuffledUnorganized(frames, opt.seed);
    for (size_t i = 0; i < configs.size() && configs[i].lanes == 1; ++i) {
      std::fprintf(stderr, "running: %s, unorganized\n", configs[i].name.c_str());
      unorganized.push_back(
          RunConfig(unorganized_frames, params, configs[i], opt.repeat, opt.warmup, 0));
    }
  }
  ProcStatus after_ours = ReadProcStatus();
  for (const ConfigResult& r : results) {
    after_ours.vm_hwm_mb = std::max(after_ours.vm_hwm_mb, r.peak_rss_mb);
  }
  for (const ConfigResult& r : unorganized) {
    after_ours.vm_hwm_mb = std::max(after_ours.vm_hwm_mb, r.peak_rss_mb);
  }
  const double maxrss_ours = MaxRssMb();

  PrintStageTable(results[0]);
  if (results.size() > 1 && results[1].config.lanes == 1) PrintStageTable(results[1]);

  std::printf("\nThroughput (%zu frames per configuration):\n", results[0].frames);
  std::printf("  %-34s %7s %9s %9s %9s %9s %9s %9s %9s\n", "configuration", "FPS", "CPU ms/fr",
              "lat mean", "lat p99", "new/fr", "malloc/fr", "KiB/fr", "+RSS MiB");
  size_t best = 0;
  for (size_t i = 0; i < results.size(); ++i) {
    const ConfigResult& r = results[i];
    const double nf = static_cast<double>(r.frames);
    if (AllocCountingAvailable()) {
      std::printf(
          "  %-34s %7.1f %9.2f %9.2f %9.2f %9.2f %9.2f %9.1f %9.1f\n", r.config.name.c_str(), r.fps,
          r.cpu_ms_per_frame, r.latency.mean, r.latency.p99,
          static_cast<double>(r.allocs.news) / nf, static_cast<double>(r.allocs.mallocs) / nf,
          static_cast<double>(r.allocs.bytes) / nf / 1024.0, r.peak_rss_mb - r.rss_before_mb);
    } else {  // a sanitizer build: its allocator cannot be counted
      std::printf("  %-34s %7.1f %9.2f %9.2f %9.2f %9s %9s %9s %9.1f\n", r.config.name.c_str(),
                  r.fps, r.cpu_ms_per_frame, r.latency.mean, r.latency.p99, "n/a", "n/a", "n/a",
                  r.peak_rss_mb - r.rss_before_mb);
    }
    if (r.fps > results[best].fps) best = i;
  }
  std::printf(
      "  (+RSS: peak RSS during the configuration minus RSS before its segmenters "
      "were created)\n");
  std::printf(
      "  (CPU ms/fr: process CPU time per frame; %d cores could process at most "
      "%d x 1000 / (CPU ms) frames per second)\n",
      threads, threads);
  std::printf("  best: %s (%.1f FPS)\n", results[best].config.name.c_str(), results[best].fps);
  std::printf(
      "  supervoxels per frame %.0f, objects per frame %.1f, valid points per frame %.0f, of "
      "which taken by the support-first step %.0f (%.1f%%)\n",
      results[0].supervoxels_mean, results[0].objects_mean, results[0].valid_points_mean,
      results[0].support_first_points_mean,
      results[0].valid_points_mean > 0
          ? 100.0 * results[0].support_first_points_mean / results[0].valid_points_mean
          : 0.0);

  if (!unorganized.empty()) {
    size_t organized_frames = 0;
    for (const core::PointCloud& c : frames.clouds) organized_frames += c.organized() ? 1 : 0;
    PrintStageTable(unorganized[0], " (unorganized)");
    std::printf(
        "\nOrganized vs unorganized (the same %zu frames, %zu of them organized, as their valid "
        "points in a shuffled order, HEIGHT 1; neighbourhoods then come from k-d trees), ms per "
        "frame:\n",
        frames.size(), organized_frames);
    std::printf("  %-24s %10s %10s %10s %10s %8s %11s %11s %9s\n", "configuration", "org mean",
                "org p99", "unorg mean", "unorg p99", "ratio", "org CPU/fr", "unorg CPU/fr",
                "new/fr");
    for (size_t i = 0; i < unorganized.size(); ++i) {
      const ConfigResult& o = results[i];
      const ConfigResult& u = unorganized[i];
      char allocs[32] = "n/a";
      if (AllocCountingAvailable()) {
        std::snprintf(allocs, sizeof(allocs), "%.2f",
                      static_cast<double>(u.allocs.news) / static_cast<double>(u.frames));
      }
      std::printf("  %-24s %10.2f %10.2f %10.2f %10.2f %7.2fx %11.2f %11.2f %9s\n",
                  u.config.name.c_str(), o.latency.mean, o.latency.p99, u.latency.mean,
                  u.latency.p99, u.latency.mean / o.latency.mean, o.cpu_ms_per_frame,
                  u.cpu_ms_per_frame, allocs);
    }
  }

  std::printf(
      "\nMemory: RSS after loading frames %.1f MiB (frames hold %.1f MiB); peak during "
      "the segmenter runs (VmHWM%s, max over configurations) %.1f MiB, i.e. %.1f MiB above the "
      "loaded state; "
      "RSS at the end %.1f MiB; ru_maxrss %.1f MiB\n",
      after_load.vm_rss_mb, frames_mb, hwm_reset ? ", reset per configuration" : "",
      after_ours.vm_hwm_mb, after_ours.vm_hwm_mb - after_load.vm_rss_mb, after_ours.vm_rss_mb,
      maxrss_ours);

#if CLUTTERSEG_BENCH_HAVE_PCL
  PclResult pcl;
  pcl_baseline::BaselineParams pcl_params;
  pcl_params.use_single_camera_transform = opt.pcl_single_camera_transform;
  pcl_params.use_extended_convexity = !opt.pcl_no_extended;
  const std::string pcl_setting =
      std::string(pcl_params.use_single_camera_transform ? "single-camera transform"
                                                         : "Euclidean voxels") +
      (pcl_params.use_extended_convexity ? ", extended convexity" : ", no extended convexity");
  const bool pcl_reset = opt.pcl && ResetPeakRss();
  if (opt.pcl) {
    std::fprintf(stderr, "running: PCL supervoxels + LCCP\n");
    pcl = RunPcl(frames, pcl_params, opt.pcl_repeat);
    pcl.peak_rss_mb = ReadProcStatus().vm_hwm_mb;
    const double ours_pool = results[0].stages.back().mean;
    const double ours_1t = results.size() > 1 ? results[1].stages.back().mean : ours_pool;
    std::printf("\nPCL supervoxels + LCCP (tools/pcl_baseline, %s; single thread), ms:\n",
                pcl_setting.c_str());
    std::printf("  %-18s %9s %9s %9s %9s %9s\n", "stage", "mean", "p50", "p90", "p99", "max");
    const std::pair<const char*, const Summary*> rows[] = {
        {"supervoxels", &pcl.supervoxels}, {"lccp", &pcl.lccp}, {"total", &pcl.total}};
    for (const auto& [name, s] : rows) {
      std::printf("  %-18s %9.2f %9.2f %9.2f %9.2f %9.2f\n", name, s->mean, s->p50, s->p90, s->p99,
                  s->max);
    }
    std::printf("  %.0f supervoxels, %.1f segments per frame; peak RSS%s %.1f MiB\n",
                pcl.supervoxels_mean_count, pcl.segments_mean, pcl_reset ? " (reset before)" : "",
                pcl.peak_rss_mb);
    std::printf(
        "  speed ratio PCL / ours (mean total): %.1fx vs %d threads, %.1fx vs 1 thread; "
        "PCL FPS %.1f vs best ours %.1f (%.1fx)\n",
        pcl.total.mean / ours_pool, threads, pcl.total.mean / ours_1t, 1000.0 / pcl.total.mean,
        results[best].fps, results[best].fps / (1000.0 / pcl.total.mean));
    const double ours_cpu =
        results.size() > 1 ? results[1].cpu_ms_per_frame : results[0].cpu_ms_per_frame;
    std::printf(
        "  CPU time per frame: PCL %.1f ms, ours %.1f ms (1 thread): %.1fx (robust "
        "to machine load)\n",
        pcl.cpu_ms_per_frame, ours_cpu, pcl.cpu_ms_per_frame / ours_cpu);
  }
#endif
  const std::string load_end = LoadAverage();

  Json stage_table = Json::array();
  for (const pipeline::StageInfo& info : pipeline::StageTable()) {
    stage_table.push_back(
        {{"name", std::string(info.name)}, {"description", std::string(info.description)}});
  }
  auto config_json = [&](const ConfigResult& r) {
    const double nf = static_cast<double>(r.frames);
    Json c = {{"name", r.config.name},
              {"lanes", r.config.lanes},
              {"pool_threads", r.config.pool_threads},
              {"fps", r.fps},
              {"cpu_ms_per_frame", r.cpu_ms_per_frame},
              {"cpu_bound_fps", 1000.0 * threads / r.cpu_ms_per_frame},
              {"alloc_counting_available", AllocCountingAvailable()}};
    if (AllocCountingAvailable()) {
      c["news_per_frame"] = static_cast<double>(r.allocs.news) / nf;
      c["mallocs_per_frame"] = static_cast<double>(r.allocs.mallocs) / nf;
      c["alloc_bytes_per_frame"] = static_cast<double>(r.allocs.bytes) / nf;
    }
    c["rss_before_mb"] = r.rss_before_mb;
    c["peak_rss_mb"] = r.peak_rss_mb;
    c["peak_rss_above_before_mb"] = r.peak_rss_mb - r.rss_before_mb;
    c["latency_ms"] = SummaryJson(r.latency);
    Json stages = Json::object();
    for (size_t i = 0; i < Stages().size(); ++i) {
      stages[Stages()[i].name] = SummaryJson(r.stages[i]);
    }
    c["stages_ms"] = std::move(stages);
    return c;
  };
  Json config_results = Json::array();
  for (const ConfigResult& r : results) config_results.push_back(config_json(r));
  // A non-finite number (a rate over no time) is written as null.
  Json w = {{"tool", "clutterseg-bench"},
            {"source", frames.source},
            {"frames", frames.size()},
            {"repeat", opt.repeat},
            {"warmup", opt.warmup},
            {"threads", threads},
            {"overrides", opt.overrides},
            {"load_avg_start", load_start},
            {"load_avg_end", load_end},
            {"stage_table", std::move(stage_table)},
            {"supervoxels_mean", results[0].supervoxels_mean},
            {"objects_mean", results[0].objects_mean},
            {"valid_points_mean", results[0].valid_points_mean},
            {"support_first_points_mean", results[0].support_first_points_mean},
            {"configs", std::move(config_results)}};
  if (!unorganized.empty()) {
    // The same frames shuffled into unorganized clouds (ShuffledUnorganized), 1-lane configs.
    Json unorganized_results = Json::array();
    for (const ConfigResult& r : unorganized) unorganized_results.push_back(config_json(r));
    w["unorganized_configs"] = std::move(unorganized_results);
  }
  w["best_config"] = results[best].config.name;
  w["best_fps"] = results[best].fps;
  w["memory_mb"] = {{"frames_heap", frames_mb},
                    {"rss_after_load", after_load.vm_rss_mb},
                    {"peak_rss_segmenter", after_ours.vm_hwm_mb},
                    {"peak_reset", hwm_reset},
                    {"peak_above_loaded", after_ours.vm_hwm_mb - after_load.vm_rss_mb},
                    {"rss_end", after_ours.vm_rss_mb},
                    {"ru_maxrss", maxrss_ours}};
#if CLUTTERSEG_BENCH_HAVE_PCL
  if (opt.pcl) {
    const double ours_pool = results[0].stages.back().mean;
    const double ours_1t = results.size() > 1 ? results[1].stages.back().mean : ours_pool;
    const double ours_cpu =
        results.size() > 1 ? results[1].cpu_ms_per_frame : results[0].cpu_ms_per_frame;
    w["pcl"] = {{"single_camera_transform", pcl_params.use_single_camera_transform},
                {"extended_convexity", pcl_params.use_extended_convexity},
                {"supervoxels_ms", SummaryJson(pcl.supervoxels)},
                {"lccp_ms", SummaryJson(pcl.lccp)},
                {"total_ms", SummaryJson(pcl.total)},
                {"supervoxels_mean", pcl.supervoxels_mean_count},
                {"segments_mean", pcl.segments_mean},
                {"peak_rss_mb", pcl.peak_rss_mb},
                {"ratio_vs_pool", pcl.total.mean / ours_pool},
                {"ratio_vs_1thread", pcl.total.mean / ours_1t},
                {"ratio_fps_best", results[best].fps * pcl.total.mean / 1000.0},
                {"cpu_ms_per_frame", pcl.cpu_ms_per_frame},
                {"ratio_cpu", pcl.cpu_ms_per_frame / ours_cpu}};
  }
#endif
  // Bytes of a string that are not UTF-8 (a directory name may hold any) are written as U+FFFD.
  const std::string json = w.dump(-1, ' ', false, Json::error_handler_t::replace);
  std::printf("%s\n", json.c_str());
  if (!opt.json_path.empty()) {
    std::ofstream out(opt.json_path, std::ios::trunc);
    out << json << '\n';
    if (!out) throw std::runtime_error("cannot write JSON file '" + opt.json_path + "'");
  }
  return kExitOk;
}

}  // namespace
}  // namespace clutterseg::bench

int main(int argc, char** argv) {
  try {
    return clutterseg::bench::Run(argc, argv);
  } catch (const std::invalid_argument& e) {  // bad options or parameters
    std::cerr << "clutterseg-bench: error: " << e.what() << '\n';
    return clutterseg::kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "clutterseg-bench: error: " << e.what() << '\n';
    return clutterseg::kExitFailure;
  }
}
