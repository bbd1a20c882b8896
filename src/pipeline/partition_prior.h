#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/objects.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/surface_history.h"
#include "clutterseg/pipeline/temporal_filter.h"

namespace clutterseg::pipeline {

/// Parameters of the PartitionPrior (configuration section `segmenter.partition`; every key is
/// named `segmenter.partition.<field>`). Frame counts are frames of the stream.
struct PartitionPriorParams {
  static constexpr std::string_view kSection = "segmenter.partition";

  /// A change of the partition of a still region (two objects of the previous frame now one
  /// segment, or one object now several) is published once the segmentation has shown it in
  /// this many consecutive frames; until then the previous frame's boundaries are kept there.
  /// 1 = every change at once (off); 4 by default (docs/results.md, "Hysteresis on the
  /// partition"). A region whose depth changed does not wait (see min_still_share).
  int hold_frames{4};
  /// A segment counts as still when at least this share of its valid pixels kept their depth
  /// within the temporal filter's band (segmenter.temporal.band_at_1m_m, min_band_m) since the
  /// previous frame (0..1]. Anything placed, removed, pushed or passing in front makes its
  /// segments not still, and their partition is published as segmented, in the same frame.
  float min_still_share{0.9f};
  /// An object of the previous frame is covered by a segment holding at least this share of
  /// its still pixels; a segment is a part of a previous object when that object holds at
  /// least this share of the segment's still pixels [0.5..1).
  float min_cover_share{0.5f};
  /// Objects and segments with fewer still pixels than this are left as segmented.
  int min_pixels{100};
  /// When a merge is held back, the pixels it cuts back to one previous object join the
  /// segment of this frame that holds the rest of that object (lying within it, covering no
  /// other), when there is one, instead of standing as a piece of their own: a previous object
  /// that the segmentation cut in two while merging one part with a neighbour is published
  /// whole, as before. false = the cut-back pixels are a piece of their own.
  bool cut_piece_joins_rest{true};

  /// Objects by arrival (docs/method.md, "Objects by arrival"): a segment joining surfaces
  /// that arrived in front of the camera more than this many frames apart (a box put flush
  /// on a box that was there before) is split along them; 0 = off (config/paper.yaml). 10 by
  /// default (docs/results.md, "Objects by arrival, with the pieces joined back").
  int arrival_gap_frames{10};
  /// A new depth at a pixel is a surface (and its arrival counted from its first frame) once
  /// measured within the band in this many consecutive frames; until then the split waits.
  int arrival_confirm_frames{5};
  /// A part of a segment of one arrival is split off when it holds at least min_pixels
  /// pixels and this share of the segment's pixels of known arrival (0..1].
  float arrival_min_share{0.05f};
  /// An object next to at least this many pixels whose surface moved away (it uncovered what
  /// was behind) has moved, and all of it counts as arrived then: a pushed object stays whole.
  int arrival_moved_min_pixels{10};
  /// A part that the arrival split cut off a segment joins the neighbouring segment of the
  /// same arrival (not the first frame's) with which it shares at least this many contacts
  /// (pairs of 4-neighbour pixels, or of pixels one unlabelled pixel apart, whose depths lie
  /// within two depth bands): the piece of an older object that the segmentation gave to a
  /// newer neighbour goes back to the rest of its object. 0 = never.
  int arrival_rejoin_min_contact{3};
  /// Segments most of whose pixels arrived in the same frame (not the first) and that touch in
  /// at least this many pairs of pixels (image neighbours along a row or a column, or up to six
  /// unlabelled pixels apart, at any depth) are one object: the pieces of one object put down
  /// that the segmentation cut apart (a cup's inside and its outside wall). Two touching
  /// objects put down in the same frame become one. With it, such segments also join across
  /// something in front of both (the ends of an object with another lying across its middle):
  /// ten rows or columns on which they are at most 64 pixels apart with only nearer pixels and
  /// holes between. 0 = never.
  int arrival_join_min_contact{3};

  /// Whether a PartitionPrior with these parameters changes anything (hold or arrivals on).
  bool enabled() const { return hold_frames > 1 || arrival_gap_frames > 0; }
  /// @throws std::invalid_argument naming the key (`segmenter.partition.<field>`) and value.
  void ValidateOrThrow() const;
  bool operator==(const PartitionPriorParams&) const = default;
};

/// Counters of one Apply.
struct PartitionPriorCounts {
  int held_merges{0};     ///< segments cut back along the previous frame's boundaries
  int held_splits{0};     ///< previous objects whose parts were joined back
  int passed_merges{0};   ///< merges of still objects published (seen hold_frames in a row)
  int passed_splits{0};   ///< splits of still objects published (seen hold_frames in a row)
  int arrival_splits{0};  ///< segments split into parts of different arrival
  int arrival_moves{0};   ///< objects that moved and count as arrived in this frame
  int arrival_joins{0};   ///< parts cut off by arrival joined to a neighbour of their arrival
};

/// Hysteresis on the partition of a stream (docs/method.md, "Temporal coherence"): where the
/// scene is still, a boundary that the segmentation opens or closes in one frame only does not
/// reach the output. Each frame's segments are compared with the previous frame's published
/// objects over the pixels whose depth stayed within the sensor's noise band. A segment that
/// covers two or more previous objects is cut back along their previous boundaries (pixels
/// that belonged to neither go to the nearest part, in the image, within the segment) until
/// the segmentation has joined that pair in hold_frames consecutive frames; parts that lie
/// within one previous object are joined back until it has split that object in hold_frames
/// consecutive frames. Then the change is published. The counts follow the segmentation, not
/// the output: a merge seen in most frames is published after hold_frames of them, a merge
/// seen now and then never is. A segment that is not still (min_still_share) is published as
/// segmented, so a change of the scene shows in the first frame that measures it; a previous
/// object is held only once most of its pixels have been still for hold_frames frames, so a
/// partition made in the frame of a change is not held either.
///
/// Before the hysteresis, the objects by arrival (SurfaceHistory, the `arrival_*` keys; docs/
/// method.md, "Objects by arrival"): segments joining surfaces put down at different times are
/// split along them; the hysteresis then holds what that changes like any other change of the
/// partition.
///
/// State per camera: the previous output's labels and depths and each pixel's still age (9
/// bytes per pixel, 2.8 MB for 640 x 480) and the surface history (30 bytes per pixel), an id per
/// previous object and a counter per pair of previous objects merged in the last frame and per
/// previous object split in it. Reset by Reset(), a frame sequence number that does not increase,
/// or a change of image size.
///
/// Organized clouds only (an unorganized cloud is passed through and resets the state).
/// Objects are renumbered 1..n and their statistics recomputed (ObjectExtractor) when a frame
/// changes. Deterministic: the output depends only on the frames given and their order.
/// Thread-safety: not reentrant; one Apply at a time, in frame order.
class PartitionPrior {
 public:
  /// `band` gives the depth band within which a pixel counts as still (its band_at_1m_m and
  /// min_band_m). `pool` (may be null; it must outlive the prior) runs the per-pixel steps in
  /// chunks; the output does not depend on it. @throws std::invalid_argument when `params` fail
  /// validation.
  PartitionPrior(const PartitionPriorParams& params, const TemporalFilterParams& band,
                 core::ThreadPool* pool = nullptr);
  ~PartitionPrior();
  PartitionPrior(const PartitionPrior&) = delete;
  PartitionPrior& operator=(const PartitionPrior&) = delete;

  /// Applies the hysteresis to `result`, the segmentation of `cloud` (same layout as its
  /// labels), frame number `frame_seq`. `scene_z` is the depth of the whole scene per pixel
  /// (Segmenter::scene_depth(): before the support planes' interiors left the cloud) that the
  /// objects by arrival follow; when it does not have one value per pixel, the cloud's z.
  /// Returns true when it changed the labels (and then the objects, renumbered and
  /// recomputed). Never throws except std::bad_alloc.
  bool Apply(const core::PointCloudView& cloud, int64_t frame_seq, SegmentationResult* result,
             std::span<const float> scene_z = {});

  /// Apply in two halves, for a caller that publishes between them: Relabel changes `result`
  /// as Apply does, and Remember keeps its output for the next frame (without the pool, so
  /// that a thread woken to publish gets a core). Remember must follow each Relabel before the
  /// next one, with `cloud` and `result` alive and unchanged (it aborts otherwise: a
  /// programming error); together they do exactly what Apply does.
  bool Relabel(const core::PointCloudView& cloud, int64_t frame_seq, SegmentationResult* result,
               std::span<const float> scene_z = {});
  /// The second half of Apply (see Relabel); does nothing when none is pending.
  void Remember();

  /// Forgets the previous frames.
  void Reset();

  const PartitionPriorParams& params() const { return params_; }
  /// The temporal filter parameters whose band it was made with.
  const TemporalFilterParams& band() const { return band_; }
  const PartitionPriorCounts& counts() const { return counts_; }
  /// Bytes of per-pixel state held for the current image size.
  size_t memory_bytes() const;

 private:
  struct PairCount {
    uint32_t a, b;  // ids of previous objects, a < b
    int count;
  };
  struct IdCount {
    uint32_t id;
    int count;
  };
  bool enabled() const { return params_.enabled(); }
  // Objects 1..num_labels of result's labels, their statistics computed again.
  void Describe(const core::PointCloudView& cloud, uint32_t num_labels, SegmentationResult* result);
  // Renumbers labels [0, num_in) of `in` to 1..count in label order into `out` (may alias).
  uint32_t Compact(uint32_t num_in, const uint32_t* in, size_t num_pixels, uint32_t* out);
  // Keeps the output `result` (its ids from `counts`, the output against the previous frame,
  // when `have_counts`) for the next frame; the per-pixel copy in chunks on `pool` (may be null).
  void RememberOutput(const core::PointCloudView& cloud, const SegmentationResult& result,
                      const std::vector<uint32_t>& counts, bool have_counts,
                      core::ThreadPool* pool);
  // Runs the pending RememberOutput (Relabel's frame), its copy on `pool` (may be null).
  void RememberPending(core::ThreadPool* pool);
  // Leaves the output of the frame Relabel finished to Remember.
  void Defer(const core::PointCloudView& cloud, const SegmentationResult* result, bool have_counts);

  // The frame whose output Remember keeps (Relabel's), null when none is pending.
  const SegmentationResult* pending_result_{nullptr};
  core::PointCloudView pending_cloud_;
  bool pending_have_counts_{false};

  PartitionPriorParams params_;
  TemporalFilterParams band_;  // its band_at_1m_m and min_band_m
  core::ThreadPool* pool_;     // may be null
  PartitionPriorCounts counts_;
  ObjectExtractor extractor_;
  SurfaceHistory history_;

  bool have_prev_{false};
  int64_t prev_seq_{0};
  int width_{0}, height_{0};
  std::vector<uint32_t> prev_labels_;
  std::vector<float> prev_z_;
  std::vector<uint8_t> still_age_;  // frames in a row each pixel has been still (to 255)
  std::vector<uint32_t> prev_id_;   // id of each previous object, by label (0 unused)
  uint32_t next_id_{1};
  std::vector<PairCount> merges_;  // by (a, b)
  std::vector<IdCount> splits_;    // by id

  // Per-frame work buffers.
  std::vector<uint8_t> state_;                   // each pixel's stillness bits (StepStillness)
  std::vector<uint32_t> tables_, chunk_tables_;  // the counts below as counted, per chunk
  std::vector<uint32_t> counts_rp_;              // (segment) x (previous label) still pixels
  std::vector<uint32_t> valid_r_, still_r_, still_p_, established_p_;
  std::vector<int> covered_n_;  // previous objects each segment covers
  std::vector<PairCount> new_merges_;
  std::vector<IdCount> new_splits_;
  std::vector<uint32_t> map_;                 // label -> output label before compaction
  std::vector<std::vector<uint32_t>> split_;  // per segment cut: previous label -> new label
  std::vector<uint32_t> out_labels_;
  std::vector<uint32_t> covered_;                 // previous objects one segment covers
  std::vector<int> parent_;                       // union-find over them
  std::vector<uint32_t> group_px_, group_label_;  // per group of them: pixels, output label
  std::vector<uint32_t> final_label_;
  std::vector<uint8_t> used_;
  std::vector<uint32_t> id_work_;              // ids of this frame's objects, by label
  std::vector<uint32_t> owner_, owner_count_;  // per previous object: its claimant
  std::vector<uint32_t> pending_, pending_next_, taken_;
};

}  // namespace clutterseg::pipeline
