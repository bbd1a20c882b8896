#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <span>
#include <vector>

#include "clutterseg/core/types.h"

namespace clutterseg::eval {

/// Parameters of the tracking evaluation. Plain struct; call ValidateOrThrow() after editing.
struct TrackingEvalParams {
  /// A ground-truth object is matched, in each frame, to the predicted object whose centroid
  /// is nearest to its centroid, when that is at most this far, metres.
  float match_distance_m{0.03f};
  /// Flicker only counts frame pairs whose ground-truth set has not changed for this many
  /// frames before them (0 = any pair with the same set), so that a delay a consumer chose on
  /// purpose (a tracker confirming new objects) does not count as flicker.
  int settle_frames{0};

  /// @throws std::invalid_argument naming the key and value (match_distance_m not > 0,
  /// settle_frames < 0).
  void ValidateOrThrow() const;
};

/// Tracking scores of one ground-truth object.
struct ObjectTrackingScore {
  uint32_t gt_id{0};
  int visible_frames{0};    ///< frames the object is in (listed in AddFrame's gt_ids)
  int matched_frames{0};    ///< of those, frames it matched a predicted object
  int64_t main_id{-1};      ///< its most frequent matched predicted id (ties: the earliest)
  int main_id_frames{0};    ///< matched frames carrying main_id
  int id_switches{0};       ///< matched frames whose id differs from the previous matched one
  int distinct_ids{0};      ///< distinct predicted ids it matched
  double consistency{0.0};  ///< main_id_frames / matched_frames (0 when never matched)
};

/// Scores of a sequence (see TrackingEvaluator for the definitions).
struct TrackingMetrics {
  int frames{0};
  int num_gt_objects{0};
  int64_t gt_object_frames{0};       ///< sum of visible_frames
  int64_t matched_object_frames{0};  ///< sum of matched_frames
  double coverage{0.0};              ///< matched_object_frames / gt_object_frames
  /// Identity consistency: sum of main_id_frames / sum of matched_frames over every object.
  double identity_consistency{0.0};
  double min_object_consistency{0.0};  ///< the lowest consistency of a matched object
  int id_switches{0};                  ///< summed over objects
  /// Predicted ids that matched more than one ground-truth object, each counted once per
  /// further object (an id carried over from one physical object to another).
  int id_reuse{0};
  int steady_pairs{0};   ///< consecutive frame pairs with the same ground-truth object set
  int flicker_pairs{0};  ///< of those, pairs whose predicted id set differs
  double flicker{0.0};   ///< flicker_pairs / steady_pairs (0 when there is none)
  std::vector<ObjectTrackingScore> objects;  ///< by increasing gt_id
};

/// Scores object identities over a sequence of frames, fed in frame order. The inputs are
/// plain arrays, so any tracker (or none: the per-frame label values) can be scored.
///
/// Definitions:
/// - In each frame every listed ground-truth object is matched to the predicted object with
///   the nearest centroid within match_distance_m (several may match the same one).
/// - Coverage: matched / listed ground-truth object-frames.
/// - Identity consistency of an object: the share of its matched frames whose predicted id
///   is its most frequent one; pooled over objects (weighted by matched frames).
/// - Id switches: changes of the matched id between consecutive matched frames of an object.
/// - Id reuse: sum over predicted ids of (distinct ground-truth objects matched - 1).
/// - Flicker: among consecutive frame pairs whose ground-truth id sets are equal (nothing
///   changed in the scene, for settle_frames frames before as well), the share whose
///   predicted id sets differ (an object appearing or vanishing, or a count change).
///
/// Thread-safety: none (one instance per sequence and thread).
class TrackingEvaluator {
 public:
  /// @throws std::invalid_argument when `params` is invalid.
  explicit TrackingEvaluator(const TrackingEvalParams& params = TrackingEvalParams{});

  /// Adds the next frame: ground-truth objects `gt_ids[i]` (distinct) at `gt_centroids[i]`,
  /// predicted objects `pred_ids[i]` at `pred_centroids[i]` (metres, one frame for both).
  /// `remembered_ids` are further predicted ids that the consumer reports as present without
  /// a position in this frame (a tracker's remembered, hidden objects): they count in the
  /// frame's predicted id set for flicker only. Paired spans must have equal sizes (checked
  /// with CLUTTERSEG_DEMAND).
  void AddFrame(std::span<const uint32_t> gt_ids, std::span<const core::Vec3f> gt_centroids,
                std::span<const int64_t> pred_ids, std::span<const core::Vec3f> pred_centroids,
                std::span<const int64_t> remembered_ids = {});

  /// The scores of the frames added so far.
  TrackingMetrics Summarize() const;

 private:
  struct ObjectAccum {
    int visible{0};
    int64_t last_id{-1};
    bool has_last{false};
    int switches{0};
    std::vector<int64_t> ids;  // matched id per matched frame, in order
  };
  TrackingEvalParams params_;
  int frames_{0};
  std::map<uint32_t, ObjectAccum> objects_;
  std::map<int64_t, std::set<uint32_t>> id_objects_;
  std::vector<uint32_t> prev_gt_, cur_gt_;
  std::vector<int64_t> prev_pred_, cur_pred_;
  int same_gt_run_{0};  // consecutive frames up to the last one with its ground-truth set
  int steady_pairs_{0};
  int flicker_pairs_{0};
};

/// Centroids of the labelled points of a frame: for every label >= 1 with at least
/// `min_points` points of finite xyz, appends the label to `ids` (increasing) and the mean
/// of its points to `centroids` (both cleared first). Spans of equal size (CLUTTERSEG_DEMAND).
void LabelCentroids(std::span<const core::Vec3f> xyz, std::span<const uint32_t> labels,
                    uint32_t min_points, std::vector<uint32_t>* ids,
                    std::vector<core::Vec3f>* centroids);

}  // namespace clutterseg::eval
