// Google Benchmark of Tracker::Update on real segmentations of a rendered tabletop (640x480)
// and on hand-made frames with many objects.
#include <cstdint>
#include <vector>

#include <benchmark/benchmark.h>

#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/pipeline/tracker.h"
#include "clutterseg/synth/random.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/sequence.h"

namespace clutterseg::pipeline {
namespace {

// Segmentations of `n` frames of a static scene with sensor noise changing per frame.
std::vector<SegmentationResult> SegmentedFrames(synth::Scenario scenario, int n) {
  synth::SceneParams scene;
  scene.camera_distance_min_m = 0.8;
  scene.camera_distance_max_m = 1.1;
  synth::SequenceParams seq;
  seq.scenario = scenario;
  seq.num_frames = n;
  seq.num_objects = 8;
  const std::vector<synth::Scene> frames = synth::GenerateScenarioSequence(scene, seq, 1);
  Segmenter segmenter{SegmenterParams{}};
  std::vector<SegmentationResult> out(frames.size());
  synth::RenderedFrame r;
  core::PointCloud cloud;
  for (size_t k = 0; k < frames.size(); ++k) {
    synth::RenderScene(frames[k], scene.intrinsics, synth::SensorParams{},
                       synth::HashCounter(1, k + 1), &r);
    synth::ToPointCloud(r, &cloud);
    segmenter.Process(cloud, scene.intrinsics, &out[k]);
  }
  return out;
}

void RunUpdates(benchmark::State& state, const std::vector<SegmentationResult>& frames) {
  Tracker tracker{TrackerParams{}};
  TrackingResult out;
  int64_t seq = 0;
  for (const SegmentationResult& f : frames) tracker.Update(f, seq++, &out);  // warm up
  size_t k = 0;
  for (auto _ : state) {
    tracker.Update(frames[k], seq++, &out);
    benchmark::DoNotOptimize(out.objects.data());
    k = (k + 1) % frames.size();
  }
  state.counters["objects"] = static_cast<double>(frames[0].objects.size());
}

void BM_TrackerStatic640x480(benchmark::State& state) {
  static const std::vector<SegmentationResult> frames =
      SegmentedFrames(synth::Scenario::kStatic, 8);
  RunUpdates(state, frames);
}
BENCHMARK(BM_TrackerStatic640x480)->Unit(benchmark::kMicrosecond);

void BM_TrackerOccluder640x480(benchmark::State& state) {
  static const std::vector<SegmentationResult> frames =
      SegmentedFrames(synth::Scenario::kOccluder, 20);
  RunUpdates(state, frames);
}
BENCHMARK(BM_TrackerOccluder640x480)->Unit(benchmark::kMicrosecond);

// `n` square objects on a 640x480 label image, shifted by one pixel every frame.
void BM_TrackerManyObjects(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::vector<SegmentationResult> frames(4);
  for (int f = 0; f < 4; ++f) {
    SegmentationResult& r = frames[static_cast<size_t>(f)];
    r.width = 640;
    r.height = 480;
    r.labels.Reset(640, 480, 0);
    for (int i = 0; i < n; ++i) {
      const int u0 = 10 + (i % 10) * 62 + f, v0 = 10 + (i / 10) * 46;
      Object o;
      o.id = static_cast<uint32_t>(i) + 1;
      for (int v = v0; v < v0 + 40; ++v) {
        for (int u = u0; u < u0 + 40; ++u) r.labels.at(u, v) = o.id;
      }
      o.num_points = 1600;
      o.centroid = core::Vec3f{0.002f * (u0 + 20), 0.002f * (v0 + 20), 1.f};
      o.aabb_min = core::Vec3f{0.002f * u0, 0.002f * v0, 0.98f};
      o.aabb_max = core::Vec3f{0.002f * (u0 + 40), 0.002f * (v0 + 40), 1.02f};
      r.objects.push_back(o);
    }
  }
  RunUpdates(state, frames);
}
BENCHMARK(BM_TrackerManyObjects)->Arg(10)->Arg(40)->Arg(100)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace clutterseg::pipeline

BENCHMARK_MAIN();
