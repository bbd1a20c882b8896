// Benchmarks of the supervoxelizer on a synthetic 640x480 table scene and, when the io module
// is built and the shared data is present, on real mOSD frames. Each run reports per-stage
// wall times (milliseconds, mean over iterations) as counters.
#include <cstdio>
#include <filesystem>
#include <string>

#include <benchmark/benchmark.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/supervoxel/supervoxelizer.h"
#include "tests/supervoxel/synthetic_scene.h"
#ifdef CLUTTERSEG_HAVE_IO
#include "clutterseg/io/pcd.h"
#endif

namespace clutterseg::supervoxel {
namespace {

void RunBench(benchmark::State& state, const core::PointCloud& cloud, bool camera_transform) {
  const int threads = static_cast<int>(state.range(0));
  core::ThreadPool pool(threads);
  SupervoxelParams params;
  params.grid.use_single_camera_transform = camera_transform;
  Supervoxelizer dut(params, &pool);
  Supervoxels out;
  dut.Compute(cloud, &out);  // warm-up: buffers reach their steady size
  SupervoxelTimings sum;
  for (auto _ : state) {
    dut.Compute(cloud, &out);
    const SupervoxelTimings& t = out.timings;
    sum.voxelize_ms += t.voxelize_ms;
    sum.adjacency_ms += t.adjacency_ms;
    sum.normals_ms += t.normals_ms;
    sum.seeding_ms += t.seeding_ms;
    sum.growth_ms += t.growth_ms;
    sum.output_ms += t.output_ms;
    benchmark::DoNotOptimize(out.pixel_label.data());
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["voxelize_ms"] = sum.voxelize_ms / n;
  state.counters["adjacency_ms"] = sum.adjacency_ms / n;
  state.counters["normals_ms"] = sum.normals_ms / n;
  state.counters["seeding_ms"] = sum.seeding_ms / n;
  state.counters["growth_ms"] = sum.growth_ms / n;
  state.counters["output_ms"] = sum.output_ms / n;
  state.counters["voxels"] = static_cast<double>(dut.voxels().size());
  state.counters["supervoxels"] = static_cast<double>(out.size());
  state.counters["points"] = static_cast<double>(cloud.CountValid());
}

const core::PointCloud& SyntheticFrame() {
  static const core::PointCloud cloud =
      testing::RenderTableScene(testing::DefaultBoxes(), 0.8, 0.7, 2.0).cloud;
  return cloud;
}

void BM_SyntheticCameraTransform(benchmark::State& state) {
  RunBench(state, SyntheticFrame(), true);
}
void BM_SyntheticEuclidean(benchmark::State& state) { RunBench(state, SyntheticFrame(), false); }
BENCHMARK(BM_SyntheticCameraTransform)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_SyntheticEuclidean)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

#ifdef CLUTTERSEG_HAVE_IO
std::filesystem::path DataDir() {
  if (const char* env = std::getenv("CLUTTERSEG_DATA")) return env;
  return CLUTTERSEG_DATA_DIR;
}

void RegisterMosd() {
  for (const char* name : {"learn0", "learn20", "learn30", "learn40"}) {
    const std::filesystem::path path = DataDir() / "mosd-learn" / (std::string(name) + ".pcd");
    if (!std::filesystem::exists(path)) {
      std::fprintf(stderr, "skipping mOSD benchmarks: %s not found\n", path.c_str());
      return;
    }
    auto cloud = std::make_shared<core::PointCloud>(io::ReadPcd(path.string()));
    for (bool transform : {true, false}) {
      const std::string bench_name =
          std::string("BM_Mosd/") + name + (transform ? "/camera_transform" : "/euclidean");
      benchmark::RegisterBenchmark(
          bench_name.c_str(),
          [cloud, transform](benchmark::State& s) { RunBench(s, *cloud, transform); })
          ->Arg(1)
          ->Arg(2)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
}
#endif

}  // namespace
}  // namespace clutterseg::supervoxel

int main(int argc, char** argv) {
#ifdef CLUTTERSEG_HAVE_IO
  clutterseg::supervoxel::RegisterMosd();
#endif
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
