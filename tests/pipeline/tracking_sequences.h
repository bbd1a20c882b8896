#pragma once

// Renders a synthetic scenario frame by frame, segments every frame with the real Segmenter,
// tracks it and scores the identities: shared by the tracker tests and measurements.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/eval/tracking_metrics.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/pipeline/temporal_filter.h"
#include "clutterseg/pipeline/tracker.h"
#include "clutterseg/synth/random.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/sequence.h"

namespace clutterseg::pipeline::tracking_test {

// Which ids are scored.
enum class IdSource {
  kLabelValue,      // no tracker: each frame's label values (the ids published today)
  kTrackAll,        // track ids of every object
  kTrackConfirmed,  // track ids of confirmed objects only (what a consumer would show);
                    // for flicker the remembered (hidden) confirmed tracks count as present
};

struct ScenarioRun {
  eval::TrackingMetrics label_value, track_all, track_confirmed;
  std::vector<TrackingResult> tracking;       // per frame
  std::vector<std::vector<uint32_t>> gt_ids;  // per frame, objects listed to the evaluator
  double tracker_ms_total{0.0};
  double tracker_ms_max{0.0};
  int frames{0};
};

// The default scene for tracking sequences: a tabletop at 0.8-1.1 m with the default
// object kinds and placements.
inline synth::SceneParams TrackingSceneParams() {
  synth::SceneParams p;
  p.camera_distance_min_m = 0.8;
  p.camera_distance_max_m = 1.1;
  return p;
}

// Ground-truth objects with fewer valid points than this are not listed (not visible enough
// to be segmented: the segmenter drops segments under 150 points).
constexpr uint32_t kMinGtPoints = 200;

inline ScenarioRun RunScenario(const synth::SceneParams& scene, const synth::SequenceParams& seq,
                               uint64_t seed, const TrackerParams& tracker_params = {},
                               core::ThreadPool* pool = nullptr,
                               const TemporalFilterParams* temporal = nullptr) {
  const std::vector<synth::Scene> frames = synth::GenerateScenarioSequence(scene, seq, seed);
  Segmenter segmenter(SegmenterParams{}, pool);
  std::unique_ptr<TemporalDepthFilter> filter;  // the daemon's filter of a stream, when given
  if (temporal != nullptr) filter = std::make_unique<TemporalDepthFilter>(*temporal);
  Tracker tracker(tracker_params, temporal != nullptr ? *temporal : TemporalFilterParams{}, pool);
  // Flicker is counted once a change of the scene is two frames old (the default delay
  // before a new object is shown, TrackerParams{}.confirm_frames - 1), for every kind of id
  // and every tracker configuration alike.
  eval::TrackingEvalParams eval_params;
  eval_params.settle_frames = TrackerParams{}.confirm_frames - 1;
  eval::TrackingEvaluator ev_label(eval_params), ev_all(eval_params), ev_confirmed(eval_params);
  synth::RenderedFrame rendered;
  core::PointCloud cloud;
  SegmentationResult result;
  TrackingResult tracking;
  std::vector<uint32_t> gt_ids;
  std::vector<core::Vec3f> gt_c, pred_c, conf_c;
  std::vector<int64_t> pred_ids, conf_ids, remembered;
  ScenarioRun run;
  for (size_t k = 0; k < frames.size(); ++k) {
    synth::RenderScene(frames[k], scene.intrinsics, synth::SensorParams{},
                       synth::HashCounter(seed, 0x7a11, k + 1), &rendered, pool);
    if (filter) filter->Apply(&rendered.depth);
    synth::ToPointCloud(rendered, &cloud);
    segmenter.Process(cloud, scene.intrinsics, &result);
    tracker.Update(result, static_cast<int64_t>(k), &tracking, segmenter.working_cloud());
    run.tracker_ms_total += tracking.time_ms;
    run.tracker_ms_max = std::max(run.tracker_ms_max, tracking.time_ms);
    eval::LabelCentroids(cloud.xyz, cloud.label, kMinGtPoints, &gt_ids, &gt_c);
    // The occluder stands for the robot's own arm passing in front: not a tabletop object.
    for (size_t g = gt_ids.size(); g-- > 0;) {
      if (gt_ids[g] == frames[k].occluder_label) {
        gt_ids.erase(gt_ids.begin() + static_cast<std::ptrdiff_t>(g));
        gt_c.erase(gt_c.begin() + static_cast<std::ptrdiff_t>(g));
      }
    }
    pred_ids.clear();
    pred_c.clear();
    conf_ids.clear();
    conf_c.clear();
    for (size_t i = 0; i < result.objects.size(); ++i) {
      pred_ids.push_back(result.objects[i].id);
      pred_c.push_back(result.objects[i].centroid);
    }
    ev_label.AddFrame(gt_ids, gt_c, pred_ids, pred_c);
    for (size_t i = 0; i < result.objects.size(); ++i) {
      pred_ids[i] = tracking.objects[i].track_id;
      if (tracking.objects[i].state == TrackState::kConfirmed) {
        conf_ids.push_back(tracking.objects[i].track_id);
        conf_c.push_back(result.objects[i].centroid);
      }
    }
    ev_all.AddFrame(gt_ids, gt_c, pred_ids, pred_c);
    remembered.clear();
    for (const LostTrack& l : tracking.lost) {
      if (l.was_confirmed) remembered.push_back(l.track_id);
    }
    ev_confirmed.AddFrame(gt_ids, gt_c, conf_ids, conf_c, remembered);
    run.tracking.push_back(tracking);
    run.gt_ids.push_back(gt_ids);
  }
  run.frames = static_cast<int>(frames.size());
  run.label_value = ev_label.Summarize();
  run.track_all = ev_all.Summarize();
  run.track_confirmed = ev_confirmed.Summarize();
  return run;
}

}  // namespace clutterseg::pipeline::tracking_test
