#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/temporal_filter.h"

namespace clutterseg::pipeline {

/// Parameters of the Tracker (configuration section `tracker:`; every key is named
/// `tracker.<field>`). Frame counts are camera frames (frame sequence numbers), so a dropped
/// frame counts as elapsed. Defaults are for a 30 Hz camera.
struct TrackerParams {
  static constexpr std::string_view kSection = "tracker";

  /// A new track is confirmed once it has been seen in this many frames (1 = at once). Until
  /// then its objects carry TrackState::kNew; a consumer that publishes confirmed objects
  /// only shows a new object confirm_frames - 1 frames late (67 ms at 30 Hz by default) and
  /// never shows one that lives shorter than that.
  int confirm_frames{3};
  /// A confirmed track that is no longer seen is remembered (TrackingResult::lost) for this
  /// many frames after the last frame it was seen in, then ended. When an object reappears
  /// near its remembered box within that time it gets the track's id back.
  int memory_frames{60};
  /// The same for a track that was not yet confirmed (0 = it ends in the first frame it is
  /// not seen in, so a short-lived spurious object leaves no memory behind).
  int tentative_memory_frames{0};
  /// With the frame's depth (Update's `scene_z` or `cloud`), a confirmed track past
  /// memory_frames is still remembered while most of its remembered surface is hidden behind
  /// something nearer than it (an object put down on it, an occluder standing in front), up to
  /// this many frames after it was last seen; it ends in the first frame its surface is not
  /// mostly hidden (in view under another object's id, or taken away). 0 = off.
  int hidden_memory_frames{900};
  /// With the frame's depth: an object more than twice as many of whose pixels came in front
  /// of what was there in this frame (surface_change_min_step_m) as it holds of a confirmed
  /// track older than joined_view_frames whose surface stayed (a newcomer put down against the
  /// track's object and segmented with it) is not that track's: it gets a new track, which
  /// leaves the old one's remembered surface out of its own until the old one is seen again or
  /// ends, and the old track is remembered and takes its surface back when it shows apart (as a
  /// merge goes to the track clearly most in view). false = the old track keeps the segment.
  bool newcomer_merge{true};
  /// A track not yet confirmed that is absorbed in a merge whose keeper holds at most twice its
  /// pixels in the segment (an object put down against another, one segment with it before its
  /// track was confirmed) is remembered for max(tentative_memory_frames, joined_view_frames)
  /// frames, and takes its id back when it shows apart (with depth, by its remembered surface).
  /// false = it ends as any track not yet confirmed (tentative_memory_frames).
  bool tentative_merge_memory{true};
  /// With the frame's depth: an object that reaches a track's previous mask only where
  /// something came in front (min_mask_overlap counted on the pixels whose surface did not
  /// change) does not continue the track. An occluder sweeping across a track whose pixels
  /// mostly fell into holes then leaves it free to take the piece of it that showed again
  /// beside the occluder by its remembered surface. false = any mask overlap continues it.
  bool occluder_is_not_continuation{true};
  /// With the frame's depth: a confirmed track seen for at least memory_frames frames and then
  /// absorbed in a merge is remembered past memory_frames while at least part_min_fraction of its
  /// remembered surface is in view on an object at its depth (its object still there, in
  /// another's segment), up to hidden_memory_frames after it was last seen, and takes its id
  /// back when it shows apart. A track seen for fewer frames (a piece split off for a few frames)
  /// ends after memory_frames. false = it ends after memory_frames.
  bool merged_memory{true};
  /// With the frame's depth: a confirmed track's view in which the pixels that were another
  /// object's in the previous frame and moved reach part_min_fraction of its own view (a surface
  /// uncovered behind an object taken away, segmented with a piece of the object behind that
  /// showed beside it) is not its reference view, nor for joined_view_frames frames while the
  /// view reaches out of the reference box: the piece's track does not take the uncovered size
  /// as its own, which would make it keep a merge with the object's larger part. false = it is.
  bool uncovered_view_not_reference{true};

  /// An object of this frame and a track seen in the previous frame are associated by their
  /// masks when their pixels overlap by at least this share of the smaller mask (0..1).
  float min_mask_overlap{0.1f};
  /// ...or, without mask overlap, when their centroids are at most this far apart, metres.
  float max_centroid_step_m{0.05f};
  /// Box diagonals of an associated object and track differ by at most this factor (>= 1).
  float max_size_ratio{3.0f};

  /// Without the frame's depth (Update's `cloud`), a remembered (lost) track is reacquired by
  /// an object whose centroid lies within this distance of the track's remembered box,
  /// metres...
  float reacquire_distance_m{0.03f};
  /// ...and whose box lies inside the remembered box by at least this share of its volume
  /// (0..1), so that a different object placed beside it does not take its id.
  float reacquire_min_box_inside{0.5f};
  /// The remembered box is the one of the track's largest recent view (an object partly
  /// hidden before it disappeared is remembered whole): the reference view's point count is
  /// multiplied by this factor in every frame it is seen and replaced by the current view
  /// when that has more points (0..1; 0 = always the last view).
  float reference_decay{0.95f};

  /// Split and merge: an object lying on a track's previous mask by at least this share of
  /// its own pixels is a part of that track; when a track has several parts, only the part
  /// with the most points keeps the track (the others get other or new ids). A track whose
  /// previous mask lies on one object by at least this share is absorbed by it; when an
  /// object absorbs several tracks, only one keeps the object and the others become
  /// lost-but-remembered: the track with more than twice the pixels of each other in the object
  /// (the others mostly hidden), else the largest track (by the point count of its largest
  /// recent view, see reference_decay; then by overlap) (0.5..1).
  float part_min_fraction{0.5f};
  /// Splits: when > 0, the part whose centroid lies nearer by more than this (metres) to the
  /// track's own last centroid keeps the track when it holds a quarter of the track's own view
  /// (not a sliver), parts within it of each other leaving it to the one with more points; a
  /// track's own centroid is that of its last view that absorbed
  /// no other track and held no remembered one (so after a merge comes apart each object
  /// gets its own id back). 0 = off: the part with the most points keeps it.
  float split_own_margin_m{0.01f};
  /// For this many frames after a new surface joined a confirmed track's view (at least
  /// part_min_fraction of the view was background in the previous frame: an object put down
  /// against it and segmented with it), a view of which the track's own view is at most
  /// 1 - part_min_fraction, and whose box lies less than part_min_fraction inside the track's
  /// remembered box (an object uncovered by a leaving occluder grows back within it), is still
  /// not the track's own. With the frame's depth, a view whose pixels that came nearer than
  /// what the previous frame showed there (surface_change_min_step_m) reach part_min_fraction
  /// of the track's own view joined it too (an object put down on it; one uncovered comes from
  /// behind), and it stays joined while the view holds the own view and part_min_fraction of
  /// what came. Meanwhile its own centroid and reference view stay those of the object alone,
  /// so that when the objects by arrival cut the newcomer off (segmenter.partition, up to
  /// arrival_confirm_frames + hold_frames - 2 frames later) the track's id goes to its own
  /// object. With the frame's depth it is also how long a surface that came in front of what
  /// was there stays a newcomer: when a track older than this splits, a part whose pixels mostly
  /// came in front within it does not keep the track while a part that stayed is there (neither
  /// came in front nor moved since the previous frame, holding a quarter of the track's own
  /// view). 0 = only the frame it joined.
  int joined_view_frames{10};

  /// Weight of mask IoU in the association score of tracks seen in the previous frame; the
  /// rest goes in equal parts to centroid proximity and 3-D box IoU (0..1).
  float mask_weight{0.5f};
  /// Scores of remembered tracks are multiplied by this factor, so an object that could
  /// continue a visible track or reacquire a lost one continues the visible one (0..1].
  float lost_score_factor{0.8f};
  /// When true, an object that continues a confirmed track seen in the previous frame is
  /// never given to a remembered track: the track's previous mask lies on the object by at
  /// least part_min_fraction of the mask, the object lies on the mask by that share of its own
  /// pixels (or is a merge the track keeps), the split and merge rules leave the pair allowed,
  /// and when the track split the object is the part nearer its own centroid by more than
  /// split_own_margin_m (a part chosen by its size alone may be the other object's). A remembered
  /// box that encloses the object (the track's largest view covered it: a merge, a piece of
  /// background beside it) would otherwise outscore a continuation whose boundary moved by
  /// noise, and hand the object a different object's id. false = the scores alone decide.
  bool continuation_before_reacquire{true};

  /// Surface change, with the frame's depth (Update's `cloud`): a pixel of a track's previous
  /// mask changed when its depth moved by at least this much (and by more than the depth band,
  /// segmenter.temporal) since the previous frame: something was put down on the track or
  /// passed in front of it, or what the track showed was taken away. Metres; above the sensor's
  /// noise and below an object's height, so that an object pushed or lifted at a usual speed
  /// (under 45 cm/s at 30 Hz) keeps its depth within it at most of its pixels.
  float surface_change_min_step_m{0.015f};
  /// A track with at least this share of its previous mask changed continues only on an object
  /// that lies on its unchanged pixels by at least part_min_fraction of the object's own pixels
  /// (what is left of it in view); otherwise it is lost-but-remembered. So an object put down
  /// on a track and merged with what is left of it gets a new id instead of the hidden
  /// object's, and when it is taken away the object below gets its own id back (0..1].
  float surface_change_min_share{0.5f};

  /// @throws std::invalid_argument naming the key `tracker.<field>` and the value.
  void ValidateOrThrow() const;
};

/// State of a track in one frame.
enum class TrackState : int8_t {
  kNew = 0,        ///< seen in fewer than TrackerParams::confirm_frames frames
  kConfirmed = 1,  ///< seen in at least confirm_frames frames (stays so while remembered)
  kLost = 2,       ///< not seen in this frame, remembered (TrackingResult::lost only)
};

/// The track of one object of the frame; TrackingResult::objects[i] belongs to
/// SegmentationResult::objects[i].
struct ObjectTrack {
  int64_t track_id{-1};    ///< >= 1, unique within the Tracker's life, never reused
  int32_t age_frames{0};   ///< frames since the track was first seen (0 in that frame)
  int32_t seen_frames{0};  ///< frames the track has been seen in, this one included
  TrackState state{TrackState::kNew};
  bool reacquired{false};  ///< the track was lost before this frame and is seen again
};

/// A track not seen in this frame and still remembered. Geometry in metres, camera frame,
/// as last seen.
struct LostTrack {
  int64_t track_id{-1};
  int32_t frames_since_seen{0};  ///< >= 1
  int32_t age_frames{0};         ///< frames since the track was first seen
  int32_t seen_frames{0};
  TrackState state{TrackState::kLost};         ///< always kLost
  bool was_confirmed{false};                   ///< false: remembered before it was confirmed
  uint32_t num_points{0};                      ///< of the last view
  core::Vec3f centroid;                        ///< of the last view
  core::Vec3f aabb_min, aabb_max;              ///< axis-aligned box of the last view
  core::Vec3f remembered_min, remembered_max;  ///< the box used for reacquisition
};

/// Counters of one Update.
struct TrackingCounts {
  int continued{0};   ///< objects that continued a track seen in the previous frame
  int reacquired{0};  ///< objects that got a remembered track back
  int created{0};     ///< objects that started a new track
  int splits{0};      ///< tracks that had several parts (split) this frame
  int merges{0};      ///< objects that absorbed several tracks (merge) this frame
};

/// The tracker's output for one frame. Reused across frames (its vectors keep their
/// capacity).
struct TrackingResult {
  int64_t frame_seq{0};
  /// True when this frame's sequence number did not increase (a restarted source): every
  /// track of the previous frames was ended (listed in ended_track_ids) before this frame.
  bool reset{false};
  std::vector<ObjectTrack> objects;  ///< aligned with SegmentationResult::objects
  std::vector<LostTrack> lost;       ///< remembered tracks, by increasing track_id
  /// Tracks that ended in this frame (lost for longer than their memory, or reset), by
  /// increasing id; their ids never appear again.
  std::vector<int64_t> ended_track_ids;
  TrackingCounts counts;
  double time_ms{0.0};  ///< wall time of this Update, milliseconds
};

/// Gives the objects of consecutive frames of one camera stable identities (docs/method.md,
/// "Object identities across frames").
///
/// Each Update associates the objects of a frame with the current tracks (those seen in the
/// previous frame and the remembered lost ones) by one optimal assignment (Hungarian method,
/// optimize::AssignmentSolver) that maximises the summed association score. A pair may be
/// associated when the object's pixels overlap the track's pixels of the previous frame
/// (same label image layout: organized WxH or an unorganized 1xN cloud in the same point
/// order), or their centroids are close and their sizes alike; a lost track only when the
/// object shows its remembered surface at its depth (with the frame's depth) or lies in its
/// remembered box (without). With depth, a track whose mask mostly shows a new surface in front
/// of it (or lost what it showed) continues only on what is left of it, and restarts its
/// reference view from it when what it showed was taken away. Splits keep the id on the largest
/// part, merges on the track clearly most in view, else the largest (see
/// TrackerParams::part_min_fraction); a segment mostly of a newcomer put down against a track's
/// object is the newcomer's (TrackerParams::newcomer_merge).
///
/// Thread-safety: one Tracker per camera; Update is not reentrant and must be called once
/// per frame in frame order (from one thread at a time, e.g. an ordered completion step).
/// It is sequential and deterministic: the same frames give the same output, whatever the
/// pool (which only runs the per-pixel depth step and overlap counts in chunks). Work buffers
/// are kept, so steady-state frames do not allocate.
/// Complexity: O(pixels + tracks x objects x min(tracks, objects)) per frame.
class Tracker {
 public:
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  /// `band` is the depth band of the sensor's noise (TemporalFilterParams::BandAt) that tells
  /// a surface that stayed from one that changed (TrackerParams::surface_change_min_step_m).
  /// `pool` may be null and must outlive the tracker.
  /// @throws std::invalid_argument when `params` or `band` fail validation (naming the key).
  explicit Tracker(const TrackerParams& params, const TemporalFilterParams& band = {},
                   core::ThreadPool* pool = nullptr);
  ~Tracker();

  /// Tracks the objects of `frame`, the segmentation of the camera frame numbered
  /// `frame_seq` (increasing; gaps count as elapsed frames, a sequence number that does not
  /// increase resets the tracker), and fills `out` (reusing its storage). `frame` must hold
  /// labels whose values are its objects' ids (as Segmenter produces). `cloud` is the frame's
  /// points in the labels' layout (Segmenter::working_cloud(), metres); with it, a new surface
  /// in front of a track does not take its id (TrackerParams::surface_change_min_share) and a
  /// remembered track is reacquired only by an object that shows its remembered surface at its
  /// depth. Empty or of another size: association by masks and geometry alone (a remembered
  /// track by its box). `scene_z` is the depth of the whole scene per pixel (metres, NaN =
  /// invalid; Segmenter::scene_depth(): before the support planes' interiors left the cloud),
  /// which tells what changed from one frame to the next: an object taken away down to the table
  /// shows the table's depth there, while the cloud has none. When it does not have one value
  /// per pixel, the cloud's z. Never throws.
  void Update(const SegmentationResult& frame, int64_t frame_seq, TrackingResult* out,
              const core::PointCloudView& cloud = {}, std::span<const float> scene_z = {});

  /// Update in two halves, for a caller that publishes between them: Associate fills `out`
  /// (the ids; TrackingResult::time_ms is its time) and RememberSurfaces keeps the surfaces
  /// of the objects seen for the next frame. RememberSurfaces must follow each Associate before
  /// the next one, with `frame` and `cloud` alive and unchanged (it aborts otherwise: a
  /// programming error); together they do exactly what Update does.
  void Associate(const SegmentationResult& frame, int64_t frame_seq, TrackingResult* out,
                 const core::PointCloudView& cloud = {}, std::span<const float> scene_z = {});
  /// The second half of Update (see Associate); does nothing when none is pending. Never
  /// throws except std::bad_alloc.
  void RememberSurfaces();

  /// Forgets every track (their ids are not reused) and the previous frame; the next Update
  /// reports them in ended_track_ids and sets TrackingResult::reset.
  void Reset();

  /// Replaces the parameters for the following Updates, keeping every track (so a
  /// configuration reload between frames does not renumber the objects). Not to be called
  /// during Update.
  /// @throws std::invalid_argument when `params` fail validation (the old ones stay).
  void SetParams(const TrackerParams& params);
  /// Replaces the depth band (a reload of `segmenter.temporal`), keeping every track. Not to
  /// be called during Update.
  /// @throws std::invalid_argument when `band` fails validation (the old one stays).
  void SetBand(const TemporalFilterParams& band);

  const TrackerParams& params() const;
  /// The id the next new track will get.
  int64_t next_track_id() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::pipeline
