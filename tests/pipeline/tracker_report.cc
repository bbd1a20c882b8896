// tracker_report: renders every synthetic scenario for a few seeds, segments each frame with
// the Segmenter, tracks it, and prints identity consistency, id switches, id reuse, coverage
// and flicker for three kinds of ids (docs/method.md, "Object identities across frames"):
//   label   - each frame's label values, i.e. no tracker (the ids published before)
//   tracks  - the tracker's ids on every object (no confirmation filter)
//   shown   - the tracker's ids on confirmed objects; remembered tracks count as present
// plus the tracker's wall time per frame. Usage:
//   tracker_report [--seeds 1,2,3] [--frames 40] [--objects 6] [--step 4] [--threads 2]
//                  [--confirm N] [--memory N] [--occluder arm|box]
//                  [--dump SCENARIO]   (per-frame tracks of SCENARIO for the first seed)
//                  [--temporal-frames N] [--temporal-band-mm MM] [--temporal-min-band-mm MM]
//                  [--temporal-hole-fill N]   (the daemon's temporal depth filter before the
//                                              segmenter; off unless one of them is given)
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "clutterseg/core/thread_pool.h"
#include "tests/pipeline/tracking_sequences.h"

namespace clutterseg::pipeline::tracking_test {
namespace {

struct Sum {
  int64_t matched{0}, main{0}, visible{0};
  int switches{0}, reuse{0}, steady{0}, flicker{0};
  void Add(const eval::TrackingMetrics& m) {
    matched += m.matched_object_frames;
    visible += m.gt_object_frames;
    for (const auto& o : m.objects) main += o.main_id_frames;
    switches += m.id_switches;
    reuse += m.id_reuse;
    steady += m.steady_pairs;
    flicker += m.flicker_pairs;
  }
  void Print(const char* scenario, const char* what) const {
    std::printf("| %-10s | %-6s | %.3f | %3d | %3d | %.3f | %3d/%-3d = %.3f |\n", scenario, what,
                matched ? static_cast<double>(main) / matched : 0.0, switches, reuse,
                visible ? static_cast<double>(matched) / visible : 0.0, flicker, steady,
                steady ? static_cast<double>(flicker) / steady : 0.0);
  }
};

void Dump(const ScenarioRun& run) {
  for (int k = 0; k < run.frames; ++k) {
    const TrackingResult& t = run.tracking[static_cast<size_t>(k)];
    std::printf("frame %2d gt [", k);
    for (uint32_t g : run.gt_ids[static_cast<size_t>(k)]) std::printf(" %u", g);
    std::printf(" ] objects");
    for (const ObjectTrack& o : t.objects) {
      std::printf(" %lld%s%s", static_cast<long long>(o.track_id),
                  o.state == TrackState::kConfirmed ? "" : "n", o.reacquired ? "R" : "");
    }
    std::printf(" lost");
    for (const LostTrack& l : t.lost) {
      std::printf(" %lld(%d)", static_cast<long long>(l.track_id), l.frames_since_seen);
    }
    std::printf(" ended");
    for (int64_t e : t.ended_track_ids) std::printf(" %lld", static_cast<long long>(e));
    std::printf(" splits %d merges %d\n", t.counts.splits, t.counts.merges);
  }
  for (const eval::ObjectTrackingScore& o : run.track_all.objects) {
    std::printf("gt %u: visible %d matched %d main id %lld consistency %.2f ids %d\n", o.gt_id,
                o.visible_frames, o.matched_frames, static_cast<long long>(o.main_id),
                o.consistency, o.distinct_ids);
  }
}

int Main(int argc, char** argv) {
  std::vector<uint64_t> seeds = {1, 2, 3};
  int frames = 40, objects = 6, step = 4, threads = 1;
  std::string dump;
  TrackerParams tracker_params;
  synth::OccluderShape occluder = synth::OccluderShape::kArm;
  TemporalFilterParams temporal;
  bool filter = false;
  std::string scenarios = "add,remove,add-remove,occluder,static";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i], value = argv[i + 1];
    if (key == "--seeds") {
      seeds.clear();
      size_t pos = 0;
      while (pos < value.size()) {
        const size_t comma = value.find(',', pos);
        seeds.push_back(std::stoull(value.substr(pos, comma - pos)));
        pos = comma == std::string::npos ? value.size() : comma + 1;
      }
    } else if (key == "--frames") {
      frames = std::stoi(value);
    } else if (key == "--objects") {
      objects = std::stoi(value);
    } else if (key == "--step") {
      step = std::stoi(value);
    } else if (key == "--threads") {
      threads = std::stoi(value);
    } else if (key == "--confirm") {
      tracker_params.confirm_frames = std::stoi(value);
    } else if (key == "--memory") {
      tracker_params.memory_frames = std::stoi(value);
    } else if (key == "--occluder") {
      occluder = synth::ParseOccluderShape(value);
    } else if (key == "--dump") {
      dump = value;
    } else if (key == "--scenarios") {
      scenarios = value;
    } else if (key == "--temporal-frames") {
      temporal.max_frames = std::stoi(value);
      filter = true;
    } else if (key == "--temporal-band-mm") {
      temporal.band_at_1m_m = std::stof(value) * 1e-3f;
      filter = true;
    } else if (key == "--temporal-min-band-mm") {
      temporal.min_band_m = std::stof(value) * 1e-3f;
      filter = true;
    } else if (key == "--temporal-hole-fill") {
      temporal.hole_fill_frames = std::stoi(value);
      filter = true;
    } else {
      std::fprintf(stderr, "tracker_report: unknown option %s\n", key.c_str());
      return 2;
    }
  }
  core::ThreadPool pool(threads);
  if (!dump.empty()) {
    synth::SequenceParams seq;
    seq.scenario = synth::ParseScenario(dump);
    seq.num_frames = frames;
    seq.num_objects = objects;
    seq.step_frames = step;
    seq.occluder_shape = occluder;
    Dump(RunScenario(TrackingSceneParams(), seq, seeds.front(), tracker_params, &pool,
                     filter ? &temporal : nullptr));
    return 0;
  }
  tracker_params.ValidateOrThrow();
  std::printf(
      "%zu seeds, %d frames, %d objects, a change every %d frames, %s occluder; tracker "
      "confirm_frames %d, memory_frames %d\n",
      seeds.size(), frames, objects, step, std::string(synth::OccluderShapeName(occluder)).c_str(),
      tracker_params.confirm_frames, tracker_params.memory_frames);
  if (filter) {
    std::printf("temporal filter: max_frames %d, band %.2f mm at 1 m, min %.2f mm, hole fill %d\n",
                temporal.max_frames, temporal.band_at_1m_m * 1e3, temporal.min_band_m * 1e3,
                temporal.hole_fill_frames);
  }
  std::printf("\n");
  std::printf("| scenario   | ids    | consistency | switches | reuse | coverage | flicker |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  std::vector<double> ms;
  std::vector<synth::Scenario> list;
  for (size_t pos = 0; pos < scenarios.size();) {
    const size_t comma = scenarios.find(',', pos);
    list.push_back(synth::ParseScenario(scenarios.substr(pos, comma - pos)));
    pos = comma == std::string::npos ? scenarios.size() : comma + 1;
  }
  for (synth::Scenario s : list) {
    Sum label, tracks, shown;
    for (uint64_t seed : seeds) {
      synth::SequenceParams seq;
      seq.scenario = s;
      seq.num_frames = frames;
      seq.num_objects = objects;
      seq.step_frames = step;
      seq.occluder_shape = occluder;
      const ScenarioRun run = RunScenario(TrackingSceneParams(), seq, seed, tracker_params, &pool,
                                          filter ? &temporal : nullptr);
      label.Add(run.label_value);
      tracks.Add(run.track_all);
      shown.Add(run.track_confirmed);
      // Steady state: the first frame of a run allocates the tracker's buffers.
      for (size_t k = 1; k < run.tracking.size(); ++k) ms.push_back(run.tracking[k].time_ms);
    }
    const std::string name(synth::ScenarioName(s));
    label.Print(name.c_str(), "label");
    tracks.Print(name.c_str(), "tracks");
    shown.Print(name.c_str(), "shown");
  }
  // Wall times on a shared machine: the tail includes preemption.
  std::sort(ms.begin(), ms.end());
  double total = 0.0;
  for (double t : ms) total += t;
  auto at = [&](double q) {
    return ms.empty() ? 0.0 : ms[static_cast<size_t>(q * static_cast<double>(ms.size() - 1))];
  };
  std::printf(
      "\ntracker Update wall time over %zu frames (first frames left out): mean %.3f ms, "
      "median %.3f, p90 %.3f, p99 %.3f, max %.3f\n",
      ms.size(), ms.empty() ? 0.0 : total / static_cast<double>(ms.size()), at(0.5), at(0.9),
      at(0.99), at(1.0));
  return 0;
}

}  // namespace
}  // namespace clutterseg::pipeline::tracking_test

int main(int argc, char** argv) { return clutterseg::pipeline::tracking_test::Main(argc, argv); }
