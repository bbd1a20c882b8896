#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/temporal_filter.h"

namespace clutterseg::pipeline {

struct PartitionPriorParams;  // partition_prior.h: the homes of its parameters

/// When each pixel's surface arrived, and the split of segments that join surfaces of
/// different arrival (docs/method.md, "Objects by arrival"). A box set flush on another box
/// continues its faces without a crease, and no single frame can tell the two apart; a camera
/// that watched the second box arrive can. Per pixel it keeps the surface it sees (depth and
/// the frame its measurement began), the surface it saw before that one (so a surface that
/// reappears after an occluder, or when what covered it is taken away, gets its arrival back)
/// and a candidate surface not yet confirmed.
///
/// A surface's arrival is known when it appeared directly in front of the pixel's previous
/// surface (something put down there); a surface that appeared behind what covered it (what
/// an occluder or a removed object uncovers, never seen before) has no known arrival and
/// follows its segment. Nor has a surface that was in no segment the first frame it was
/// labelled (the table, the wall): where an object put down is within the depth band of the
/// support behind it (the flank of a can lying down) it shows the support's surface, whose
/// arrival says nothing about the object. A segment whose pixels of known arrival fall into groups
/// more than gap_frames apart, each large enough, is split along them. An object that moves
/// (pushed, picked up and put back) uncovers what was behind it; the segment next to such pixels
/// takes the new arrival for all its surfaces of the old one, so a pushed object stays one object.
///
/// State per pixel: 30 bytes and 1 of scratch (9.5 MB for 640 x 480; memory_bytes()), 4 more
/// when the depths are read from the cloud (no scene depth given), none while off
/// (gap_frames 0). Frame numbers are kept relative to the first frame after a Reset() (int32:
/// two years at 30 Hz). Deterministic: the output depends only on the frames and labels given
/// and their order, whatever the pool. Thread-safety: not reentrant; one Apply at a time,
/// frames in order.
class SurfaceHistory {
 public:
  /// Its parameters are the `arrival_*` keys and min_pixels of `params` (0 arrival_gap_frames
  /// = off, no state kept) and the depth band of `band` (band_at_1m_m, min_band_m). `pool` (may
  /// be null; it must outlive the history) runs the per-pixel step in chunks of pixels.
  SurfaceHistory(const PartitionPriorParams& params, const TemporalFilterParams& band,
                 core::ThreadPool* pool = nullptr);

  /// Forgets every pixel's history.
  void Reset();

  /// Updates the history with frame `seq` (an organized cloud laid out like `labels`; the
  /// depths read are `scene_z`'s, metres, NaN = invalid, when it has one per pixel, else the
  /// cloud's z), then splits the segments of `labels` (0 = none, 1..n objects) that hold
  /// surfaces of different arrival. Parts split off take labels n+1, n+2, ...; returns the
  /// number of labels (n when nothing was split; changed() says whether anything was). Pixels
  /// of no known arrival in a split segment go to the nearest part within it.
  uint32_t Apply(const core::PointCloudView& cloud, std::span<const float> scene_z, int64_t seq,
                 uint32_t n, uint32_t* labels);

  /// Segments split by the last Apply; segments that took a new arrival for having moved.
  int num_split() const { return num_split_; }
  int num_moved() const { return num_moved_; }
  /// Parts cut off by the last Apply that joined a neighbouring segment of their arrival.
  int num_joined() const { return num_joined_; }
  /// Whether the last Apply changed the labels.
  bool changed() const { return changed_; }
  size_t memory_bytes() const;

 private:
  struct Moved {
    uint32_t label;
    int32_t birth;  // arrival of the surface that moved away
    int32_t since;  // frame of the move
    uint32_t count;
  };
  struct Entry {
    int32_t birth;
    uint32_t count;
  };
  void Update(const core::PointCloudView& cloud, std::span<const float> scene_z, int32_t now);
  // The arrival of pixel i's surface (relative frame), -1 when unknown.
  int32_t Arrival(size_t i) const;
  bool changed_{false};
  void ApplyMoves(const uint32_t* labels, uint32_t n, int w, int h);
  // Joins, in the labels `out` (one per pixel, segments up to `num_labels`), the parts cut off
  // to the neighbouring segment of their arrival (arrival_rejoin_min_contact), and the
  // segments that arrived together (MarkTogether) and touch (arrival_join_min_contact).
  void Rejoin(const core::PointCloudView& cloud, uint32_t num_labels, uint32_t* out);
  // Whether `frame` was a new view (kMaxNewViews; also when it is older than those kept).
  bool NewView(int32_t frame) const;
  // Whether most pixels of segments a and b arrived (not in the first frame, nor in a new view)
  // within kJoinMaxPeakFrames of each other.
  bool ArrivedTogether(uint32_t a, uint32_t b) const;
  // Marks in together_ the segments up to `num_labels` that arrived together with another
  // (none with arrival_join_min_contact 0); whether any did.
  bool MarkTogether(uint32_t num_labels);

  struct Params {  // copied from PartitionPriorParams
    int gap_frames, confirm_frames, min_pixels, moved_min_pixels, rejoin_min_contact,
        join_min_contact;
    float min_share;
  };
  Params params_;
  TemporalFilterParams band_;  // its depth band (BandAt)
  core::ThreadPool* pool_;     // may be null
  bool have_{false};
  int64_t base_seq_{0};
  size_t num_pixels_{0};
  int num_split_{0}, num_moved_{0}, num_joined_{0};

  // Per pixel. z in metres (NaN = none); births and sinces relative to base_seq_.
  std::vector<float> ref_z_, old_z_, cand_z_;
  std::vector<int32_t> ref_birth_, ref_since_, old_birth_, cand_since_;
  std::vector<uint8_t> cand_n_, flags_;
  // The frames in which most of the image left its surface (a new view), increasing, the last
  // kMaxNewViews of them; whether older ones were dropped.
  std::vector<int32_t> new_views_;
  bool new_views_dropped_{false};

  // Per frame.
  std::vector<float> z_;                 // the cloud's depths, when no scene depth is given
  const float* depth_{nullptr};          // this frame's depths (the scene's, or z_), in Apply
  std::vector<uint8_t> todo_;            // pixels left to the full rules by Update's first pass
  uint32_t last_changed_{0};             // pixels of a valid depth not on their surface, last frame
  std::vector<uint32_t> chunk_changed_;  // the same per chunk of this frame's step
  std::vector<uint32_t> uncovered_;      // pixels that uncovered a surface of known arrival
  std::vector<int32_t> uncovered_birth_, uncovered_since_;
  std::vector<Moved> moved_;
  std::vector<std::vector<Entry>> runs_;  // per segment: runs of pixels of one arrival
  // The same per chunk of pixels (chunk-major: chunk k's segment r at k * (n + 1) + r), counted
  // on the pool and appended to runs_ in chunk order.
  std::vector<std::vector<Entry>> chunk_runs_;
  std::vector<std::vector<Entry>> entries_;  // per segment: arrivals and pixel counts
  std::vector<uint32_t> group_px_, label_of_;
  std::vector<std::vector<uint32_t>> to_;  // per segment, per entry: output label (0 = fill)
  std::vector<uint32_t> out_, pending_, pending_next_, taken_;
  // Per output label: the arrival range of its (largest) group and the arrival of most of that
  // group's pixels, -1 = none; the segment it was cut from (itself when not split); whether it
  // is a part of a split segment.
  std::vector<int32_t> lo_, hi_, peak_;
  std::vector<uint32_t> origin_, parent_;
  std::vector<uint8_t> part_, together_;
  struct Contact {
    uint32_t a, b;
    uint32_t count;    // within reach of a part's rejoin (Rejoin)
    uint32_t wide;     // within reach of the join of one arrival's pieces
    uint32_t bridged;  // pairs on either side of something in front of both (an occluder)
  };
  std::vector<Contact> contacts_;
  std::vector<int32_t> group_lo_, group_hi_;
  std::vector<size_t> group_peak_;  // per group, the index in entries_ of its largest arrival
};

/// Gives each pixel i of `pending` (out[i] == 0) the output label of a 4-neighbour with the
/// same input label `in` (an image `w` x `h`), in passes (the labels taken in a pass are
/// written after it, so the order does not matter), at most 64; pixels still unreached take
/// their input label. `pending_next` and `taken` are work buffers. Shared by the
/// partition prior's cut and the arrival split.
void FillFromNeighbours(const uint32_t* in, int w, int h, std::vector<uint32_t>* pending,
                        std::vector<uint32_t>* pending_next, std::vector<uint32_t>* taken,
                        uint32_t* out);

}  // namespace clutterseg::pipeline
