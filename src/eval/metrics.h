#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"

namespace clutterseg::eval {

/// How raw ground-truth labels map to object ids (0 = background, never scored).
enum class GtConvention {
  kPlain,        ///< "plain": 0 background, every label >= 1 is one object
  kMosdParts,    ///< "mosd-parts": 0..9 background (1..9 = table parts), each label >= 10 is
                 ///< its own object part (the primary mOSD score)
  kMosdObjects,  ///< "mosd-objects": 0..9 background, object id = label / 10, so parts
                 ///< 20..29 form object 2 (the secondary mOSD score)
  kOcid,         ///< "ocid": labels listed in EvalParams::ocid_background_labels are
                 ///< background (default {0, 1, 2}: unlabelled, table, floor), others objects
};

/// Parses a convention name: "plain", "mosd-parts", "mosd-objects" or "ocid".
/// @throws std::invalid_argument naming the value when it is none of these.
GtConvention ParseGtConvention(std::string_view name);

/// The name ParseGtConvention accepts for `convention`.
std::string_view GtConventionName(GtConvention convention);

/// Parameters of the evaluation. Plain struct; call ValidateOrThrow() after editing.
struct EvalParams {
  GtConvention gt_convention{GtConvention::kPlain};
  /// Raw labels treated as background under GtConvention::kOcid (ignored otherwise).
  std::vector<uint32_t> ocid_background_labels{0, 1, 2};
  /// A segment "covers" a ground-truth object when it holds at least this percentage of the
  /// object's points: the threshold of the over/under-segmentation counts. Integer so the
  /// comparison `100 * |g ∩ s| >= percent * |g|` is exact.
  int min_coverage_percent{10};

  /// @throws std::invalid_argument naming the key and value (min_coverage_percent outside
  /// [1, 100]).
  void ValidateOrThrow() const;
};

/// Maps one raw ground-truth label to its object id under `params` (0 = background).
uint32_t MapGroundTruthLabel(uint32_t raw_label, const EvalParams& params);

/// Scores of one ground-truth object g_i.
struct ObjectScore {
  uint32_t gt_id{0};            ///< object id after the convention mapping (>= 1)
  size_t size{0};               ///< |g_i|, valid points
  uint32_t best_segment{0};     ///< label of s_i; 0 when no segment overlaps g_i
  size_t best_segment_size{0};  ///< |s_i| over valid points (including background ones)
  size_t intersection{0};       ///< |g_i ∩ s_i| = |TP_i|
  double overlap{0.0};          ///< Ov_i = IoU(g_i, s_i) = max_j IoU(g_i, s_j)
  double tp{0.0};               ///< |TP_i| / |g_i|
  double fp{0.0};               ///< |FP_i| / |s_i|  (0 when there is no s_i)
  double fn{0.0};               ///< |FN_i| / |g_i|  (1 when there is no s_i)
  int covering_segments{0};     ///< segments holding >= min_coverage_percent of g_i
  bool over_segmented{false};   ///< covering_segments >= 2
  bool under_segmented{false};  ///< a covering segment also covers another GT object
};

/// Metrics of one frame (METHOD.md section 7).
///
/// Definitions, over points with finite xyz only (a NaN point counts on neither side):
/// - g_i: the points whose mapped ground-truth id is i >= 1; s_j: the points whose predicted
///   label is j >= 1 (predicted label 0 is "no object" and never matches anything).
/// - Ov_i = max_j |g_i ∩ s_j| / |g_i ∪ s_j|; wov = sum |g_i| Ov_i / sum |g_i|.
/// - s_i, "the segment of maximum overlap with g_i": METHOD.md names Ov_i the overlap, so
///   s_i is the segment of maximum IoU with g_i (the one that gives Ov_i), among segments
///   with |g_i ∩ s_j| > 0. Ties on IoU go to the larger intersection, then to the smaller
///   label. IoUs are compared exactly (integer cross-multiplication).
/// - TP_i = |g_i ∩ s_i| / |g_i|, FP_i = |s_i \ g_i| / |s_i|, FN_i = |g_i \ s_i| / |g_i|;
///   |s_i| includes the segment's points on background (leakage counts as false positive).
///   When no segment overlaps g_i: TP_i = 0, FN_i = 1, FP_i = 0 (there is no segment whose
///   points could be false positives).
/// - tp, fp, fn: means over ground-truth objects; precision = tp / (tp + fp), recall =
///   tp / (tp + fn), f1 = 2 P R / (P + R). A 0/0 ratio is defined as 0, so an empty
///   prediction scores precision = recall = f1 = 0.
/// - Over-segmented object: g_i covered (>= min_coverage_percent of its points) by two or
///   more segments. Under-segmented object: g_i covered by a segment that also covers
///   another ground-truth object.
/// - Where the overlap is lost: 1 - wov = sum |g_i| (1 - Ov_i) / sum |g_i|, and object i's
///   part of it is shared equally by its error points FN_i and FP_i (each weighs
///   |g_i| / |g_i ∪ s_i|). An error point's cause is one of four, so that
///   wov + loss_merged + loss_split + loss_boundary + loss_background = 1:
///   * merged: a point of g_i in a segment covering g_i and another object, or a point of
///     s_i \ g_i on an object that s_i covers (objects in one segment);
///   * split: a point of g_i in a segment covering no other object and mostly on objects (a
///     piece of g_i alone);
///   * boundary: a point of g_i in a segment covering another object but not g_i, or a
///     point of s_i \ g_i on an object that s_i does not cover (a border between objects
///     drawn in the wrong place);
///   * background: a point of g_i predicted 0 or in a segment covering no other object and
///     mostly on the ground truth's background (a method without a background label calls
///     the table a segment), or a point of s_i on the background (a border with the table or
///     the scene).
/// A frame without ground-truth objects has `scored == false` and all ratios 0; it is left
/// out of the means of Summarize().
struct FrameMetrics {
  size_t num_points{0};        ///< points in the frame
  size_t num_valid_points{0};  ///< points with finite xyz
  int num_gt_objects{0};       ///< ground-truth objects with >= 1 valid point
  int num_segments{0};         ///< predicted labels >= 1 with >= 1 valid point
  bool scored{false};          ///< num_gt_objects > 0
  double wov{0.0};
  double tp{0.0};
  double fp{0.0};
  double fn{0.0};
  double precision{0.0};
  double recall{0.0};
  double f1{0.0};
  int over_segmented{0};             ///< ground-truth objects that are over-segmented
  int under_segmented{0};            ///< ground-truth objects that are under-segmented
  double loss_merged{0.0};           ///< the part of 1 - wov lost to merges (see above)
  double loss_split{0.0};            ///< ... to pieces of an object standing alone
  double loss_boundary{0.0};         ///< ... to borders between objects
  double loss_background{0.0};       ///< ... to borders with the background
  std::vector<ObjectScore> objects;  ///< one per ground-truth object, by increasing gt_id
};

namespace internal {

/// Open-addressing hash map from a 64-bit key to a count, reused across frames.
class CountTable {
 public:
  /// Empties the table, keeping its capacity.
  void Clear();
  /// Adds `count` (> 0) to the entry of `key`.
  void Add(uint64_t key, size_t count);
  /// Appends every (key, count) entry, in no particular order.
  void AppendEntries(std::vector<std::pair<uint64_t, size_t>>* entries) const;

 private:
  void Grow();
  std::vector<uint64_t> keys_;
  std::vector<size_t> counts_;  // 0 = empty slot
  size_t size_{0};
};

}  // namespace internal

/// Scores frames. Keeps its scratch buffers between calls, so one instance scoring a
/// sequence allocates only while frames grow. Not thread-safe: use one instance per thread.
/// Cost: O(n) over the points plus O(k log k) over the k distinct (object, segment) pairs
/// (a sparse contingency table), about 1 ms for a 640x480 frame.
class FrameEvaluator {
 public:
  /// @throws std::invalid_argument when `params` is invalid.
  explicit FrameEvaluator(const EvalParams& params);

  /// Scores one frame: point k has coordinates `xyz[k]`, raw ground-truth label
  /// `gt_labels[k]` (mapped by the convention) and predicted label `pred_labels[k]`.
  /// The three spans must have equal sizes (checked with CLUTTERSEG_DEMAND).
  void Evaluate(std::span<const core::Vec3f> xyz, std::span<const uint32_t> gt_labels,
                std::span<const uint32_t> pred_labels, FrameMetrics* metrics);

  /// Scores `pred.label` against `gt.label`, points matched by index; validity comes from
  /// `gt.xyz` (the prediction's coordinates are not used).
  /// @throws std::runtime_error when either cloud has no label field or the point counts
  /// differ.
  void Evaluate(const core::PointCloud& gt, const core::PointCloud& pred, FrameMetrics* metrics);

  const EvalParams& params() const { return params_; }

 private:
  const EvalParams params_;
  // Scratch: contingency counts keyed by (gt_id << 32 | pred), then sorted by key.
  internal::CountTable table_;
  std::vector<std::pair<uint64_t, size_t>> pairs_;
  std::vector<std::pair<uint64_t, size_t>> pairs_by_segment_;  // keys (pred << 32 | gt id)
  std::vector<std::pair<uint32_t, size_t>> segment_sizes_;
  std::vector<std::pair<uint32_t, int>> segment_cover_counts_;
};

/// Aggregate over a sequence of frames.
struct Summary {
  int frames{0};         ///< frames scored or not
  int frames_scored{0};  ///< frames with >= 1 ground-truth object
  // Means over the scored frames of the per-frame values (0 when no frame is scored).
  double wov{0.0};
  double tp{0.0};
  double fp{0.0};
  double fn{0.0};
  double precision{0.0};
  double recall{0.0};
  double f1{0.0};
  double loss_merged{0.0};
  double loss_split{0.0};
  double loss_boundary{0.0};
  double loss_background{0.0};
  // Totals over all frames, and their means per frame (over all frames).
  long gt_objects{0};
  long segments{0};
  long over_segmented{0};
  long under_segmented{0};
  double mean_gt_objects{0.0};
  double mean_segments{0.0};
  double mean_over_segmented{0.0};
  double mean_under_segmented{0.0};
};

/// Aggregates per-frame metrics: quality figures are the mean of the per-frame values over
/// frames with ground truth (each frame weighs the same); counts are summed and averaged
/// over all frames.
Summary Summarize(std::span<const FrameMetrics> frames);

}  // namespace clutterseg::eval
