#include "clutterseg/eval/tracking_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "clutterseg/core/assert.h"
#include "clutterseg/core/param_check.h"

namespace clutterseg::eval {

void TrackingEvalParams::ValidateOrThrow() const {
  const core::ParamCheck check("tracking_eval");
  check.Positive("match_distance_m", match_distance_m, "m");
  check.AtLeast("settle_frames", settle_frames, 0);
}

TrackingEvaluator::TrackingEvaluator(const TrackingEvalParams& params) : params_(params) {
  params_.ValidateOrThrow();
}

void TrackingEvaluator::AddFrame(std::span<const uint32_t> gt_ids,
                                 std::span<const core::Vec3f> gt_centroids,
                                 std::span<const int64_t> pred_ids,
                                 std::span<const core::Vec3f> pred_centroids,
                                 std::span<const int64_t> remembered_ids) {
  CLUTTERSEG_DEMAND(gt_ids.size() == gt_centroids.size());
  CLUTTERSEG_DEMAND(pred_ids.size() == pred_centroids.size());
  const double max_d2 = static_cast<double>(params_.match_distance_m) * params_.match_distance_m;
  for (size_t g = 0; g < gt_ids.size(); ++g) {
    ObjectAccum& acc = objects_[gt_ids[g]];
    ++acc.visible;
    int best = -1;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (size_t p = 0; p < pred_ids.size(); ++p) {
      const double dx = gt_centroids[g].x - pred_centroids[p].x;
      const double dy = gt_centroids[g].y - pred_centroids[p].y;
      const double dz = gt_centroids[g].z - pred_centroids[p].z;
      const double d2 = dx * dx + dy * dy + dz * dz;
      if (d2 < best_d2) {
        best_d2 = d2;
        best = static_cast<int>(p);
      }
    }
    if (best < 0 || best_d2 > max_d2) continue;
    const int64_t id = pred_ids[static_cast<size_t>(best)];
    if (acc.has_last && id != acc.last_id) ++acc.switches;
    acc.last_id = id;
    acc.has_last = true;
    acc.ids.push_back(id);
    id_objects_[id].insert(gt_ids[g]);
  }

  cur_gt_.assign(gt_ids.begin(), gt_ids.end());
  std::sort(cur_gt_.begin(), cur_gt_.end());
  cur_pred_.assign(pred_ids.begin(), pred_ids.end());
  cur_pred_.insert(cur_pred_.end(), remembered_ids.begin(), remembered_ids.end());
  std::sort(cur_pred_.begin(), cur_pred_.end());
  same_gt_run_ = frames_ > 0 && cur_gt_ == prev_gt_ ? same_gt_run_ + 1 : 1;
  if (same_gt_run_ >= params_.settle_frames + 2) {
    ++steady_pairs_;
    if (cur_pred_ != prev_pred_) ++flicker_pairs_;
  }
  prev_gt_.swap(cur_gt_);
  prev_pred_.swap(cur_pred_);
  ++frames_;
}

TrackingMetrics TrackingEvaluator::Summarize() const {
  TrackingMetrics m;
  m.frames = frames_;
  m.num_gt_objects = static_cast<int>(objects_.size());
  int64_t main_frames = 0;
  m.min_object_consistency = 1.0;
  bool any_matched = false;
  for (const auto& [gt_id, acc] : objects_) {
    ObjectTrackingScore s;
    s.gt_id = gt_id;
    s.visible_frames = acc.visible;
    s.matched_frames = static_cast<int>(acc.ids.size());
    s.id_switches = acc.switches;
    // Most frequent id; ties go to the id matched first.
    std::map<int64_t, int> count;
    for (int64_t id : acc.ids) ++count[id];
    s.distinct_ids = static_cast<int>(count.size());
    for (int64_t id : acc.ids) {
      const int c = count[id];
      if (c > s.main_id_frames) {
        s.main_id_frames = c;
        s.main_id = id;
      }
    }
    if (s.matched_frames > 0) {
      s.consistency = static_cast<double>(s.main_id_frames) / s.matched_frames;
      m.min_object_consistency = std::min(m.min_object_consistency, s.consistency);
      any_matched = true;
    }
    m.gt_object_frames += s.visible_frames;
    m.matched_object_frames += s.matched_frames;
    main_frames += s.main_id_frames;
    m.id_switches += s.id_switches;
    m.objects.push_back(s);
  }
  if (!any_matched) m.min_object_consistency = 0.0;
  m.coverage = m.gt_object_frames > 0
                   ? static_cast<double>(m.matched_object_frames) / m.gt_object_frames
                   : 0.0;
  m.identity_consistency = m.matched_object_frames > 0
                               ? static_cast<double>(main_frames) / m.matched_object_frames
                               : 0.0;
  for (const auto& [id, gts] : id_objects_) m.id_reuse += static_cast<int>(gts.size()) - 1;
  m.steady_pairs = steady_pairs_;
  m.flicker_pairs = flicker_pairs_;
  m.flicker = steady_pairs_ > 0 ? static_cast<double>(flicker_pairs_) / steady_pairs_ : 0.0;
  return m;
}

void LabelCentroids(std::span<const core::Vec3f> xyz, std::span<const uint32_t> labels,
                    uint32_t min_points, std::vector<uint32_t>* ids,
                    std::vector<core::Vec3f>* centroids) {
  CLUTTERSEG_DEMAND(xyz.size() == labels.size());
  ids->clear();
  centroids->clear();
  uint32_t max_label = 0;
  for (uint32_t l : labels) max_label = std::max(max_label, l);
  if (max_label == 0) return;
  struct Sum {
    double x{0}, y{0}, z{0};
    uint32_t n{0};
  };
  std::vector<Sum> sums(static_cast<size_t>(max_label) + 1);
  for (size_t i = 0; i < xyz.size(); ++i) {
    if (labels[i] == 0 || !core::IsValid(xyz[i])) continue;
    Sum& s = sums[labels[i]];
    s.x += xyz[i].x;
    s.y += xyz[i].y;
    s.z += xyz[i].z;
    ++s.n;
  }
  for (uint32_t l = 1; l <= max_label; ++l) {
    const Sum& s = sums[l];
    if (s.n == 0 || s.n < min_points) continue;
    ids->push_back(l);
    centroids->push_back(core::Vec3f{static_cast<float>(s.x / s.n), static_cast<float>(s.y / s.n),
                                     static_cast<float>(s.z / s.n)});
  }
}

}  // namespace clutterseg::eval
