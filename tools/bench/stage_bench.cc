// Google Benchmark microbenchmarks of each segmentation stage on one real mOSD frame (skipped
// when the shared data is absent) and one synthetic frame, with 1 and 2 pool threads.
//
//   clutterseg_stage_bench [--benchmark_filter=...]   (CLUTTERSEG_BENCH_PCD=FILE overrides
//                                                      the mOSD frame)
// Arguments of every benchmark: frame (0 = mOSD, 1 = synthetic), pool threads.

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/geometry/voxel_grid.h"
#include "clutterseg/graph/linkage.h"
#include "clutterseg/graph/patch_features.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/optimize/planes.h"
#include "clutterseg/pipeline/objects.h"
#include "clutterseg/pipeline/overlay.h"
#include "clutterseg/pipeline/refine.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/pipeline/segmenter_params.h"
#include "clutterseg/pipeline/working_cloud.h"
#include "clutterseg/supervoxel/supervoxelizer.h"
#include "tools/bench/frame_set.h"
#if CLUTTERSEG_BENCH_HAVE_DAEMON
#include "clutterseg/daemon/messages.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#endif

namespace clutterseg::bench {
namespace {

constexpr int kMosdFrame = 0;

// The input of one frame and every stage's output, computed once per (frame, threads).
struct StageInputs {
  pipeline::SegmenterParams params;
  core::CameraIntrinsics intrinsics;
  core::PointCloud cloud;  // as loaded
  core::PointCloud work;   // restricted to the depth range, as the Segmenter does
  std::unique_ptr<core::ThreadPool> pool;
  supervoxel::Supervoxels sv;
  graph::PatchFeatures features;
  graph::LinkageResult link;
  optimize::PlaneLabeling planes;
  pipeline::SegmentationResult result;
};

std::string MosdFramePath() {
  if (const char* env = std::getenv("CLUTTERSEG_BENCH_PCD")) return env;
  return std::string(CLUTTERSEG_DATA_DIR) + "/mosd-learn/learn10.pcd";
}

// Returns null (and sets the skip message) when the frame is unavailable.
StageInputs* GetInputs(benchmark::State& state) {
  static std::map<std::pair<int64_t, int64_t>, std::unique_ptr<StageInputs>> cache;
  const int64_t frame = state.range(0);
  const int64_t threads = state.range(1);
  auto& slot = cache[{frame, threads}];
  if (slot) return slot.get();
  auto in = std::make_unique<StageInputs>();
  if (frame == kMosdFrame) {
    const std::string path = MosdFramePath();
    if (!std::filesystem::exists(path)) {
      state.SkipWithError(("mOSD frame not found: " + path).c_str());
      return nullptr;
    }
    in->cloud = io::ReadPcd(path);
    in->intrinsics = core::DefaultKinectIntrinsics();
  } else {
    FrameSet set = RenderSyntheticFrames(1, 7, 0);
    in->cloud = std::move(set.clouds[0]);
    in->intrinsics = set.intrinsics;
  }
  if (threads > 1) in->pool = std::make_unique<core::ThreadPool>(static_cast<int>(threads));
  core::ThreadPool* pool = in->pool.get();

  pipeline::WorkingCloudBuilder points(in->params.points, pool);
  pipeline::WorkingCloud work;
  points.Compute(in->cloud, in->params.supervoxel.color_importance > 0.f, &work);
  in->work = std::move(work.cloud);
  supervoxel::Supervoxelizer svz(in->params.supervoxel, pool);
  svz.Compute(in->work, &in->sv);
  graph::PatchFeatureExtractor fx(pool);
  fx.Compute(in->work, in->sv, &in->features);
  graph::Linkage linkage(in->params.linkage, pool);
  graph::LinkageCues cues;
  cues.cloud = in->cloud;
  linkage.Compute(in->sv, in->features, cues, &in->link);
  optimize::PlaneLabeler labeler(in->params.planes);
  labeler.Compute(in->sv, in->features, &in->planes);
  pipeline::Segmenter segmenter(in->params, pool);
  segmenter.Process(in->cloud, in->intrinsics, &in->result);
  slot = std::move(in);
  return slot.get();
}

void SetLabel(benchmark::State& state, const StageInputs& in) {
  state.SetLabel((state.range(0) == kMosdFrame ? "mosd" : "synthetic") + std::string("/t") +
                 std::to_string(state.range(1)) + " sv=" + std::to_string(in.sv.size()));
}

void BM_Voxelize(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  const bool color = in->params.supervoxel.color_importance > 0.f;
  geometry::Voxelizer voxelizer(in->params.supervoxel.grid, in->pool.get());
  geometry::VoxelGrid grid;
  for (auto _ : state) {
    voxelizer.Voxelize(in->work, color, &grid);
    voxelizer.ComputeAdjacency(&grid);
    benchmark::DoNotOptimize(grid.adjacency.data());
  }
  state.counters["voxels"] = static_cast<double>(grid.size());
  SetLabel(state, *in);
}

void BM_Normals(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  const bool color = in->params.supervoxel.color_importance > 0.f;
  geometry::Voxelizer voxelizer(in->params.supervoxel.grid, in->pool.get());
  geometry::VoxelGrid grid;
  voxelizer.Voxelize(in->work, color, &grid);
  voxelizer.ComputeAdjacency(&grid);
  for (auto _ : state) {
    voxelizer.ComputeNormals(&grid);
    benchmark::DoNotOptimize(grid.normal.data());
  }
  SetLabel(state, *in);
}

// The whole supervoxelizer; its sub-steps are reported as counters (ms, last iteration).
void BM_Supervoxels(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  supervoxel::Supervoxelizer svz(in->params.supervoxel, in->pool.get());
  supervoxel::Supervoxels sv;
  for (auto _ : state) {
    svz.Compute(in->work, &sv);
    benchmark::DoNotOptimize(sv.pixel_label.data());
  }
  const supervoxel::SupervoxelTimings& t = sv.timings;
  state.counters["voxelize_ms"] = t.voxelize_ms;
  state.counters["adjacency_ms"] = t.adjacency_ms;
  state.counters["normals_ms"] = t.normals_ms;
  state.counters["seeding_ms"] = t.seeding_ms;
  state.counters["growth_ms"] = t.growth_ms;
  state.counters["output_ms"] = t.output_ms;
  SetLabel(state, *in);
}

void BM_Features(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  graph::PatchFeatureExtractor fx(in->pool.get());
  graph::PatchFeatures features;
  for (auto _ : state) {
    fx.Compute(in->work, in->sv, &features);
    benchmark::DoNotOptimize(features.normal.data());
  }
  SetLabel(state, *in);
}

void BM_Linkage(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  graph::Linkage linkage(in->params.linkage, in->pool.get());
  graph::LinkageResult link;
  graph::LinkageCues cues;  // as the Segmenter passes them (an organized frame)
  cues.cloud = in->cloud;
  for (auto _ : state) {
    linkage.Compute(in->sv, in->features, cues, &link);
    benchmark::DoNotOptimize(link.segment.data());
  }
  state.counters["segments"] = link.num_segments;
  SetLabel(state, *in);
}

void BM_PlanesExpansion(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  optimize::PlaneLabeler labeler(in->params.planes);
  optimize::PlaneLabeling planes;
  for (auto _ : state) {
    labeler.Compute(in->sv, in->features, &planes);
    benchmark::DoNotOptimize(planes.patch_plane.data());
  }
  state.counters["planes"] = static_cast<double>(planes.planes.size());
  state.counters["cycles"] = planes.expansion_cycles;
  SetLabel(state, *in);
}

void BM_RefineObjects(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  pipeline::Refiner refiner(in->params.objects, in->pool.get());
  pipeline::ObjectExtractor extractor(in->pool.get());
  pipeline::SegmentationResult result;
  for (auto _ : state) {
    result.labels.Reset(in->work.width, in->work.height, 0u);
    refiner.Compute(in->intrinsics, in->work, in->sv, in->features, in->link, in->planes, &result);
    extractor.Compute(in->cloud, &result);
    benchmark::DoNotOptimize(result.objects.data());
  }
  state.counters["objects"] = static_cast<double>(result.objects.size());
  SetLabel(state, *in);
}

void BM_Segmenter(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  pipeline::Segmenter segmenter(in->params, in->pool.get());
  pipeline::SegmentationResult result;
  for (auto _ : state) {
    segmenter.Process(in->cloud, in->intrinsics, &result);
    benchmark::DoNotOptimize(result.labels.data.data());
  }
  state.counters["objects"] = static_cast<double>(result.objects.size());
  SetLabel(state, *in);
}

// Back-projection of a depth image (the daemon's first step, ProcessDepth's "points"): the
// frame's depths in millimetres, restricted to the segmenter's depth range.
void BM_DepthToPointCloud(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  core::DepthImage depth(in->cloud.width, in->cloud.height, 0);
  for (size_t i = 0; i < depth.data.size() && i < in->cloud.xyz.size(); ++i) {
    const float z = in->cloud.xyz[i].z;
    depth.data[i] = std::isfinite(z) && z > 0.f && z < 65.f
                        ? static_cast<uint16_t>(std::lround(z * 1000.f))
                        : uint16_t{0};
  }
  core::PointCloud cloud;
  size_t valid = 0;
  for (auto _ : state) {
    valid = core::DepthToPointCloud(depth, in->intrinsics, nullptr, &cloud,
                                    in->params.points.min_depth_m, in->params.points.max_depth_m,
                                    in->pool.get());
    benchmark::DoNotOptimize(cloud.xyz.data());
  }
  state.counters["valid"] = static_cast<double>(valid);
  SetLabel(state, *in);
}

// Reading the mOSD frame's PCD file (binary_compressed, LZF) into a reused cloud, as
// clutterseg-segment's lanes do; the file is in the page cache after the first iteration.
void BM_ReadPcd(benchmark::State& state) {
  const std::string path = MosdFramePath();
  if (!std::filesystem::exists(path)) {
    state.SkipWithError(("mOSD frame not found: " + path).c_str());
    return;
  }
  core::PointCloud cloud;
  for (auto _ : state) {
    io::ReadPcd(path, io::ReadLimits{}, &cloud);
    benchmark::DoNotOptimize(cloud.xyz.data());
  }
  state.SetLabel("mosd binary_compressed");
}

// Writing a labelled 640x480 cloud as binary PCD (clutterseg-segment's output) to a
// temporary file.
void BM_WritePcd(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  core::PointCloud cloud = in->cloud;
  cloud.label = in->result.labels.data;
  const std::string path =
      (std::filesystem::temp_directory_path() / "clutterseg_bench_write.pcd").string();
  for (auto _ : state) io::WritePcd(path, cloud, io::PcdEncoding::kBinary);
  std::filesystem::remove(path);
  SetLabel(state, *in);
}

// One overlay as the daemon's overlay sink makes it: the labels drawn over the frame's image
// with boxes and a legend, then written as a PNG by a reused io::PngWriter (libdeflate level
// 1) to a temporary file. Arg `write`: 0 renders only, 1 renders and writes.
void BM_Overlay(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  core::ColorImage base;
  pipeline::CloudToImage(in->cloud, &base);
  std::vector<pipeline::OverlayObject> objects;
  pipeline::OverlayObjectsFrom(in->result.objects, &objects);
  core::ColorImage image;
  io::PngWriter writer;
  const std::string path =
      (std::filesystem::temp_directory_path() / "clutterseg_bench_overlay.png").string();
  for (auto _ : state) {
    pipeline::RenderOverlay(in->result.labels, &base, objects, &image);
    if (state.range(2) != 0) writer.WriteColor(path, image);
    benchmark::DoNotOptimize(image.data.data());
  }
  std::filesystem::remove(path);
  SetLabel(state, *in);
}

#if CLUTTERSEG_BENCH_HAVE_DAEMON
daemon::FrameInfo MakeInfo(const StageInputs& in) {
  daemon::FrameInfo info;
  info.utime = 1;
  info.frame_seq = 1;
  info.camera_name = "camera";
  info.intrinsics = in.intrinsics;
  return info;
}

// objects_t conversion and LCM encoding (what the daemon does per frame before publish).
void BM_EncodeObjects(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  const daemon::FrameInfo info = MakeInfo(*in);
  clutterseg::objects_t msg;
  std::vector<uint8_t> buf;
  for (auto _ : state) {
    daemon::ToObjectsMessage(in->result, info, &msg);
    const int size = msg.getEncodedSize();
    if (buf.size() < static_cast<size_t>(size)) buf.resize(static_cast<size_t>(size));
    benchmark::DoNotOptimize(msg.encode(buf.data(), 0, size));
  }
  state.counters["bytes"] = msg.getEncodedSize();
  SetLabel(state, *in);
}

// label_image_t for each compression (range(2): 0 none, 1 RLE, 2 zlib) and LCM encoding.
void BM_EncodeLabels(benchmark::State& state) {
  StageInputs* in = GetInputs(state);
  if (in == nullptr) return;
  const daemon::FrameInfo info = MakeInfo(*in);
  const daemon::LabelCompression kinds[] = {daemon::LabelCompression::kNone,
                                            daemon::LabelCompression::kRle,
                                            daemon::LabelCompression::kZlib};
  const daemon::LabelCompression compression = kinds[state.range(2)];
  clutterseg::label_image_t msg;
  std::vector<uint8_t> buf;
  for (auto _ : state) {
    daemon::EncodeLabelImage(in->result.labels, info, compression, &msg);
    const int size = msg.getEncodedSize();
    if (buf.size() < static_cast<size_t>(size)) buf.resize(static_cast<size_t>(size));
    benchmark::DoNotOptimize(msg.encode(buf.data(), 0, size));
  }
  state.counters["bytes"] = msg.getEncodedSize();
  SetLabel(state, *in);
  state.SetLabel(state.range(2) == 0 ? "none" : state.range(2) == 1 ? "rle" : "zlib");
}
#endif

void StageArgs(benchmark::internal::Benchmark* b) {
  b->ArgNames({"frame", "threads"})->ArgsProduct({{0, 1}, {1, 2}});
  b->Unit(benchmark::kMillisecond)->UseRealTime();
}

BENCHMARK(BM_Voxelize)->Apply(StageArgs);
BENCHMARK(BM_Normals)->Apply(StageArgs);
BENCHMARK(BM_Supervoxels)->Apply(StageArgs);
BENCHMARK(BM_Features)->Apply(StageArgs);
BENCHMARK(BM_Linkage)->Apply(StageArgs);
BENCHMARK(BM_PlanesExpansion)->Apply(StageArgs);
BENCHMARK(BM_RefineObjects)->Apply(StageArgs);
BENCHMARK(BM_Segmenter)->Apply(StageArgs);
BENCHMARK(BM_DepthToPointCloud)->Apply(StageArgs);
BENCHMARK(BM_ReadPcd)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WritePcd)->Args({0, 1})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Overlay)
    ->ArgNames({"frame", "threads", "write"})
    ->ArgsProduct({{0, 1}, {1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
#if CLUTTERSEG_BENCH_HAVE_DAEMON
BENCHMARK(BM_EncodeObjects)->Apply(StageArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_EncodeLabels)
    ->ArgNames({"frame", "threads", "compression"})
    ->ArgsProduct({{0, 1}, {1}, {0, 1, 2}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();
#endif

}  // namespace
}  // namespace clutterseg::bench

BENCHMARK_MAIN();
