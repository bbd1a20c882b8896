// Google Benchmark of TemporalDepthFilter::Apply on rendered 640x480 depth frames: a static
// tabletop (every pixel averaged) and an arm sweeping across it (its pixels reset). Each
// iteration copies a raw frame into the buffer the filter works on, as the daemon's frame
// slot holds it; BM_CopyOnly640x480 is that copy alone.
#include <cstdint>
#include <vector>

#include <benchmark/benchmark.h>

#include "clutterseg/pipeline/temporal_filter.h"
#include "clutterseg/synth/random.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/sequence.h"
#include "tests/pipeline/tracking_sequences.h"

namespace clutterseg::pipeline {
namespace {

std::vector<core::DepthImage> RenderedDepth(synth::Scenario scenario, int n) {
  const synth::SceneParams scene = tracking_test::TrackingSceneParams();
  synth::SequenceParams seq;
  seq.scenario = scenario;
  seq.num_frames = n;
  seq.num_objects = 8;
  const std::vector<synth::Scene> frames = synth::GenerateScenarioSequence(scene, seq, 1);
  std::vector<core::DepthImage> out;
  synth::RenderedFrame r;
  for (size_t k = 0; k < frames.size(); ++k) {
    synth::RenderScene(frames[k], scene.intrinsics, synth::SensorParams{},
                       synth::HashCounter(1, k + 1), &r);
    out.push_back(r.depth);
  }
  return out;
}

void RunFilter(benchmark::State& state, const std::vector<core::DepthImage>& frames, bool apply) {
  TemporalDepthFilter filter{TemporalFilterParams{}};
  core::DepthImage work;
  for (const core::DepthImage& f : frames) {  // warm up: the history of a running stream
    work = f;
    filter.Apply(&work);
  }
  size_t k = 0;
  for (auto _ : state) {
    work.data.assign(frames[k].data.begin(), frames[k].data.end());
    if (apply) filter.Apply(&work);
    benchmark::DoNotOptimize(work.data.data());
    k = (k + 1) % frames.size();
  }
}

void BM_TemporalFilterStatic640x480(benchmark::State& state) {
  static const std::vector<core::DepthImage> frames = RenderedDepth(synth::Scenario::kStatic, 8);
  RunFilter(state, frames, true);
}
BENCHMARK(BM_TemporalFilterStatic640x480)->Unit(benchmark::kMicrosecond);

void BM_TemporalFilterOccluder640x480(benchmark::State& state) {
  static const std::vector<core::DepthImage> frames = RenderedDepth(synth::Scenario::kOccluder, 20);
  RunFilter(state, frames, true);
}
BENCHMARK(BM_TemporalFilterOccluder640x480)->Unit(benchmark::kMicrosecond);

void BM_CopyOnly640x480(benchmark::State& state) {
  static const std::vector<core::DepthImage> frames = RenderedDepth(synth::Scenario::kStatic, 8);
  RunFilter(state, frames, false);
}
BENCHMARK(BM_CopyOnly640x480)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace clutterseg::pipeline

BENCHMARK_MAIN();
