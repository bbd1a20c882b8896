#include "clutterseg/pipeline/tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "clutterseg/core/assert.h"
#include "clutterseg/core/label_scan.h"
#include "clutterseg/core/param_check.h"
#include "clutterseg/optimize/assignment.h"

namespace clutterseg::pipeline {
namespace {

// An association that passed its gate scores at least this much, so that a gated pair is
// never confused with a forbidden one (score 0).
constexpr double kMinScore = 1e-3;

struct Box {
  core::Vec3f min, max;
};

// The share of a track's own view that a part of a split must hold to keep the track by lying
// nearest its own centroid (TrackerParams::split_own_margin_m): an object put down on a track
// may hide more than half of it, and what is left of it keeps the track; a sliver between two
// halves of an object cut by one put down across it does not.
constexpr float kOwnPartMinShare = 0.25f;

// A merge goes to the track with more than this many times the pixels in the object of every
// other track it absorbed, before the size of their remembered views is compared: sizes in view
// that differ by less flip with the segmentation's noise, and the remembered size holds still.
constexpr uint32_t kMergeInViewFactor = 2;

// The saturated value of a pixel's frames since its surface came in front (StepDepths).
constexpr int32_t kNeverInFront = 255;

float Distance(const core::Vec3f& a, const core::Vec3f& b) {
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

float Diagonal(const Box& b) { return Distance(b.min, b.max); }

// Per pixel into `changed` when `compare`: bit 0 set when its depth moved by at least
// max(min_step, the band at its previous depth) since `prev_z`, bit 1 when it came nearer by
// that much (a surface in front of what was there); 0 where either depth is NaN. `prev_z` is set
// to this frame's depth. `front_age` counts the frames since the pixel's surface came in front
// of what was there (0 in that frame; kNeverInFront when it never did, or went back since).
// `depth(i)` is pixel i's depth (metres, NaN = invalid). Without branches and with restrict
// pointers: the compiler vectorises it.
template <class Depth>
void StepDepths(size_t num, Depth depth, float min_step, const TemporalFilterParams band,
                bool compare, float* __restrict prev_z, uint8_t* __restrict changed,
                uint8_t* __restrict front_age) {
  if (compare) {
    for (size_t i = 0; i < num; ++i) {
      const float z = depth(i), before = prev_z[i];
      const float step = std::max(min_step, band.BandAt(before)), nearer = before - z;
      const int32_t moved = std::fabs(nearer) >= step, came = nearer >= step;
      changed[i] = static_cast<uint8_t>(moved | (came << 1));
      const int32_t aged = std::min(static_cast<int32_t>(front_age[i]) + 1, kNeverInFront);
      front_age[i] = static_cast<uint8_t>(came ? 0 : (moved ? kNeverInFront : aged));
      prev_z[i] = z;
    }
  } else {
    for (size_t i = 0; i < num; ++i) {
      prev_z[i] = depth(i);
      front_age[i] = kNeverInFront;
    }
  }
}

float Volume(const Box& b) {
  return std::max(0.f, b.max.x - b.min.x) * std::max(0.f, b.max.y - b.min.y) *
         std::max(0.f, b.max.z - b.min.z);
}

float IntersectionVolume(const Box& a, const Box& b) {
  const float dx = std::min(a.max.x, b.max.x) - std::max(a.min.x, b.min.x);
  const float dy = std::min(a.max.y, b.max.y) - std::max(a.min.y, b.min.y);
  const float dz = std::min(a.max.z, b.max.z) - std::max(a.min.z, b.min.z);
  return dx > 0.f && dy > 0.f && dz > 0.f ? dx * dy * dz : 0.f;
}

float BoxIou(const Box& a, const Box& b) {
  const float inter = IntersectionVolume(a, b);
  const float uni = Volume(a) + Volume(b) - inter;
  return uni > 0.f ? inter / uni : 0.f;
}

// Distance from `p` to the box (0 inside).
float DistanceToBox(const core::Vec3f& p, const Box& b) {
  const float dx = std::max({b.min.x - p.x, 0.f, p.x - b.max.x});
  const float dy = std::max({b.min.y - p.y, 0.f, p.y - b.max.y});
  const float dz = std::max({b.min.z - p.z, 0.f, p.z - b.max.z});
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Share of `inner`'s volume inside `outer` (a flat box counts as inside when its centre is).
float InsideShare(const Box& inner, const Box& outer) {
  const float v = Volume(inner);
  if (v <= 0.f) {
    const core::Vec3f c{0.5f * (inner.min.x + inner.max.x), 0.5f * (inner.min.y + inner.max.y),
                        0.5f * (inner.min.z + inner.max.z)};
    return DistanceToBox(c, outer) == 0.f ? 1.f : 0.f;
  }
  return IntersectionVolume(inner, outer) / v;
}

bool SizesAlike(float diag_a, float diag_b, float max_ratio) {
  const float lo = std::max(std::min(diag_a, diag_b), 1e-3f);
  return std::max(diag_a, diag_b) <= max_ratio * lo;
}

}  // namespace

void TrackerParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("confirm_frames", confirm_frames, 1, 1000);
  check.InRange("memory_frames", memory_frames, 0, 100000);
  check.InRange("tentative_memory_frames", tentative_memory_frames, 0, memory_frames);
  check.InRange("hidden_memory_frames", hidden_memory_frames, 0, 1000000, "(0 = off)");
  check.Require(min_mask_overlap > 0.f && min_mask_overlap <= 1.f, "min_mask_overlap",
                min_mask_overlap, "a share in (0, 1]");
  check.Require(max_centroid_step_m > 0.f && max_centroid_step_m <= 10.f, "max_centroid_step_m",
                max_centroid_step_m, "a distance in (0, 10] m");
  check.InRange("max_size_ratio", max_size_ratio, 1.f, 100.f);
  check.Require(reacquire_distance_m > 0.f && reacquire_distance_m <= 10.f, "reacquire_distance_m",
                reacquire_distance_m, "a distance in (0, 10] m");
  check.InRange("reacquire_min_box_inside", reacquire_min_box_inside, 0.f, 1.f);
  check.InRange("reference_decay", reference_decay, 0.f, 1.f);
  check.InRange("part_min_fraction", part_min_fraction, 0.5f, 1.f);
  check.Require(split_own_margin_m >= 0.f && split_own_margin_m <= 1.f, "split_own_margin_m",
                split_own_margin_m, "a distance in [0, 1] m (0 = off)");
  check.InRange("joined_view_frames", joined_view_frames, 0, 100000);
  check.InRange("mask_weight", mask_weight, 0.f, 1.f);
  check.Require(lost_score_factor > 0.f && lost_score_factor <= 1.f, "lost_score_factor",
                lost_score_factor, "a factor in (0, 1]");
  check.Require(surface_change_min_step_m > 0.f && surface_change_min_step_m <= 1.f,
                "surface_change_min_step_m", surface_change_min_step_m, "a distance in (0, 1] m");
  check.Require(surface_change_min_share > 0.f && surface_change_min_share <= 1.f,
                "surface_change_min_share", surface_change_min_share, "a share in (0, 1]");
}

struct Tracker::Impl {
  struct Track {
    int64_t id{0};
    int64_t first_seq{0};
    int64_t last_seq{0};
    int32_t seen{0};
    bool confirmed{false};
    uint32_t prev_label{0};  // its label in the previous frame's image, 0 when not seen there
    uint32_t num_points{0};
    core::Vec3f centroid;
    Box box;
    float ref_points{0.f};  // decayed point count of the reference view
    Box ref_box;
    // The reference view's surface, with the frame's depth: its pixels and their depth
    // (metres), increasing pixel order (RememberSurface). Empty without depth.
    std::vector<uint32_t> remembered_pixels;
    std::vector<float> remembered_z;
    core::Vec3f own_centroid;    // of its last view that held no other track
    uint32_t own_points{0};      // of that view
    int64_t joined_seq{-1};      // the last frame a new surface joined its view (-1: never)
    int64_t uncovered_seq{-1};   // the last frame an uncovered surface joined it (-1: never)
    uint32_t stacked_points{0};  // of that view, the pixels that came in front (0: none)
    // The track whose segment this one began on, a newcomer joined to it (-1: none): the
    // other's remembered surface is not this one's (LeaveOutSurface).
    int64_t newcomer_of{-1};
    // A track not yet confirmed absorbed in a merge whose keeper was not clearly more in view:
    // remembered like a confirmed one, for joined_view_frames frames.
    bool absorbed_tentative{false};
    // A confirmed track absorbed in a merge, not seen since: remembered while its surface
    // stays in view (TrackerParams::merged_memory).
    bool merged_away{false};
  };

  Impl(const TrackerParams& p, const TemporalFilterParams& b, core::ThreadPool* q)
      : params(p), band(b), pool(q) {
    params.ValidateOrThrow();
    band.ValidateOrThrow();
  }

  void EndAll(TrackingResult* out) {
    for (const Track& t : tracks) out->ended_track_ids.push_back(t.id);
    tracks.clear();
    have_prev = false;
    prev_labels.clear();
    prev_z.clear();
  }

  void Associate(const SegmentationResult& frame, int64_t seq, TrackingResult* out,
                 const core::PointCloudView& cloud, std::span<const float> scene_z);
  // The second half of a frame's update (Tracker::RememberSurfaces).
  void RememberSurfaces();

  // The surfaces Associate left to RememberSurfaces: its frame and cloud, and per track (its
  // index in `tracks`) the object whose surface it remembers and that object's pixel count.
  struct SurfaceToRemember {
    size_t track;
    int det;
    uint32_t num_pixels;
  };
  const SegmentationResult* remember_frame{nullptr};  // null: nothing pending
  core::PointCloudView remember_cloud;
  std::vector<SurfaceToRemember> to_remember;

  // Object `o` of `frame` (`num_pixels` pixels), `t`'s reference view, becomes its remembered
  // surface (none without depth). Reads the object's image box; the whole image when the box
  // does not hold all its pixels.
  static void RememberSurface(const SegmentationResult& frame, const Object& o, uint32_t num_pixels,
                              const core::PointCloudView& cloud, Track* t) {
    t->remembered_pixels.clear();
    t->remembered_z.clear();
    const int w = frame.labels.width, h = frame.labels.height;
    if (cloud.empty() || w <= 0 || h <= 0) return;
    auto scan = [&](int u0, int v0, int u1, int v1) {
      for (int v = v0; v <= v1; ++v) {
        const size_t row = static_cast<size_t>(v) * static_cast<size_t>(w);
        for (int u = u0; u <= u1; ++u) {
          if (frame.labels.data[row + static_cast<size_t>(u)] != o.id) continue;
          t->remembered_pixels.push_back(static_cast<uint32_t>(row + static_cast<size_t>(u)));
          t->remembered_z.push_back(cloud.xyz[row + static_cast<size_t>(u)].z);
        }
      }
    };
    scan(std::clamp(o.pixel_min_u, 0, w - 1), std::clamp(o.pixel_min_v, 0, h - 1),
         std::clamp(o.pixel_max_u, 0, w - 1), std::clamp(o.pixel_max_v, 0, h - 1));
    if (t->remembered_pixels.size() < num_pixels) {
      t->remembered_pixels.clear();
      t->remembered_z.clear();
      scan(0, 0, w - 1, h - 1);
    }
  }

  // Removes from `t`'s remembered surface the pixels of `other`'s at about the same depth
  // (within the depth band); both are in increasing pixel order.
  void LeaveOutSurface(const Track& other, Track* t) const {
    const std::vector<uint32_t>& op = other.remembered_pixels;
    size_t j = 0, left = 0;
    for (size_t k = 0; k < t->remembered_pixels.size(); ++k) {
      const uint32_t i = t->remembered_pixels[k];
      const float z = t->remembered_z[k];
      while (j < op.size() && op[j] < i) ++j;
      if (j < op.size() && op[j] == i &&
          std::fabs(z - other.remembered_z[j]) <= band.BandAt(other.remembered_z[j])) {
        continue;
      }
      t->remembered_pixels[left] = i;
      t->remembered_z[left] = z;
      ++left;
    }
    t->remembered_pixels.resize(left);
    t->remembered_z.resize(left);
  }

  // Frames a track is remembered after it was last seen.
  int MemoryFrames(const Track& t) const {
    if (t.confirmed) return params.memory_frames;
    return t.absorbed_tentative
               ? std::max(params.tentative_memory_frames, params.joined_view_frames)
               : params.tentative_memory_frames;
  }

  TrackerParams params;
  TemporalFilterParams band;
  core::ThreadPool* pool;     // may be null: the per-pixel passes in chunks
  std::vector<Track> tracks;  // by increasing id
  int64_t next_id{1};
  bool have_prev{false};      // a previous frame exists (prev_seq valid)
  bool reset_pending{false};  // Reset() was called since the last Update
  int64_t prev_seq{0};
  int prev_width{0}, prev_height{0};
  std::vector<uint32_t> prev_labels;
  uint32_t prev_max_label{0};
  // The depth of the previous frame's labelled pixels (metres; empty when it had no cloud).
  std::vector<float> prev_z;

  // Per-frame work buffers.
  std::vector<int32_t> label_to_det;
  std::vector<uint32_t> counts;  // (prev label) x (current label) pixel contingency
  // Of those, the pixels whose surface changed (a surface in front, or taken away); the row of
  // previous label 0 holds an object's pixels that were background and moved.
  std::vector<uint32_t> changed_counts;
  std::vector<uint32_t> overlap_tables, chunk_tables;  // counts and changed_counts, counted
  // Per pixel: its depth moved since the previous frame (bit 0), nearer (bit 1).
  std::vector<uint8_t> depth_changed;
  std::vector<uint32_t> changed_size;  // per prev label
  std::vector<uint32_t> came_size;  // per prev label: of changed_size, the pixels that came nearer
  std::vector<uint32_t> nearer_size;  // per current label: its pixels that came nearer
  // Per pixel: frames since its surface came in front (kNeverInFront: not since it went back).
  std::vector<uint8_t> front_age;
  // Per current label: its pixels whose surface came in front within joined_view_frames, and
  // those whose depth moved since the previous frame (changed_counts' column sums).
  std::vector<uint32_t> front_size, moved_size;
  std::vector<uint8_t> changed_track;
  std::vector<uint8_t> by_surface;      // per track (see the association scores)
  std::vector<int64_t> newcomer_from;   // per object: the track it is a newcomer on (-1: none)
  std::vector<uint8_t> keep_tentative;  // per track: absorbed_tentative from this frame
  std::vector<uint8_t> merged_now;      // per track: merged_away from this frame
  std::vector<uint8_t> surface_pair;    // per object, of one track: allowed by its surface alone
  // Per remembered track and object: the object's pixels showing the track's remembered
  // surface (at its depth, within the band).
  std::vector<uint32_t> shown;
  size_t surface_layout{0};  // the pixel count the remembered surfaces index
  std::vector<uint32_t> prev_size, cur_size;
  std::vector<double> score, cost;
  std::vector<int32_t> row_to_col, det_track;
  std::vector<uint8_t> merged_det;
  std::vector<uint8_t> split_by_size;
  std::vector<Track> kept;
  optimize::AssignmentSolver solver;
};

void Tracker::Impl::Associate(const SegmentationResult& frame, int64_t seq, TrackingResult* out,
                              const core::PointCloudView& cloud, std::span<const float> scene_z) {
  CLUTTERSEG_DEMAND(remember_frame == nullptr);  // RememberSurfaces of the last frame ran
  to_remember.clear();
  out->frame_seq = seq;
  out->reset = false;
  out->objects.clear();
  out->lost.clear();
  out->ended_track_ids.clear();
  out->counts = TrackingCounts{};
  if (reset_pending || (have_prev && seq <= prev_seq)) {
    out->reset = true;
    EndAll(out);
    reset_pending = false;
  }

  const int num_dets = static_cast<int>(frame.objects.size());
  uint32_t cur_max_label = 0;
  for (const Object& o : frame.objects) cur_max_label = std::max(cur_max_label, o.id);
  label_to_det.assign(static_cast<size_t>(cur_max_label) + 1, -1);
  // Segmenter numbers its objects 1..n: then every label up to the largest is an object.
  bool ids_contiguous = cur_max_label == static_cast<uint32_t>(num_dets);
  for (int d = 0; d < num_dets; ++d) {
    const uint32_t id = frame.objects[static_cast<size_t>(d)].id;
    ids_contiguous = ids_contiguous && id != 0 && label_to_det[id] < 0;
    if (id != 0) label_to_det[id] = d;
  }

  // Pixel overlap between the previous frame's tracks and this frame's objects.
  const size_t num_pixels = frame.labels.data.size();
  const bool overlap = have_prev && num_pixels > 0 && prev_labels.size() == num_pixels &&
                       prev_width == frame.labels.width && prev_height == frame.labels.height;
  const size_t stride = static_cast<size_t>(cur_max_label) + 1;
  // The frame's depth, in the labels' layout.
  const bool with_depth = num_pixels > 0 && cloud.size() == num_pixels;
  const bool compare_depth = overlap && with_depth && prev_z.size() == num_pixels;
  // Pixels [b, e) through StepDepths on the whole scene's depth when given (a surface taken
  // away down to a support plane shows its depth there), else the cloud's; one loop per depth
  // source, so each vectorises.
  const bool scene = with_depth && scene_z.size() == num_pixels;
  auto step_depths = [&](size_t b, size_t e, bool compare) {
    if (scene) {
      const float* z = scene_z.data() + b;
      StepDepths(
          e - b, [z](size_t k) { return z[k]; }, params.surface_change_min_step_m, band, compare,
          prev_z.data() + b, depth_changed.data() + b, front_age.data() + b);
    } else if (with_depth) {
      const core::Vec3f* xyz = cloud.xyz.data() + b;
      StepDepths(
          e - b, [xyz](size_t k) { return xyz[k].z; }, params.surface_change_min_step_m, band,
          compare, prev_z.data() + b, depth_changed.data() + b, front_age.data() + b);
    }
  };
  if (with_depth && prev_z.size() != num_pixels) {
    prev_z.assign(num_pixels, 0.f);
    front_age.assign(num_pixels, static_cast<uint8_t>(kNeverInFront));
  }
  if (!with_depth) {
    prev_z.clear();
    front_age.clear();
  }
  if (with_depth && num_pixels != surface_layout) {  // another layout: forget the surfaces
    for (Track& t : tracks) {
      t.remembered_pixels.clear();
      t.remembered_z.clear();
    }
    surface_layout = num_pixels;
  }
  nearer_size.clear();
  front_size.clear();
  moved_size.clear();
  came_size.clear();
  if (overlap) {
    counts.assign((static_cast<size_t>(prev_max_label) + 1) * stride, 0u);
    changed_counts.assign(compare_depth ? counts.size() : 0, 0u);
    // Per chunk of pixels (on the pool): the depth steps first (every pixel, vectorised; only
    // those of a track's pixels are read), then the overlap and the changed pixels of it,
    // keeping this frame's labels for the next one. Most pixels are background in both frames
    // (core::ForEachLabelled skips them).
    if (with_depth) depth_changed.resize(num_pixels);
    uint32_t* prev = prev_labels.data();
    const uint32_t* cur = frame.labels.data.data();
    const uint8_t* moved = depth_changed.data();
    const uint8_t* age = front_age.data();
    const int32_t recent = std::min(params.joined_view_frames, kNeverInFront - 1);
    const bool contiguous = ids_contiguous;
    const size_t table = counts.size();
    const size_t nearer_table = compare_depth ? stride : 0;
    const size_t came_table = compare_depth ? static_cast<size_t>(prev_max_label) + 1 : 0;
    overlap_tables.assign(table + changed_counts.size() + 2 * nearer_table + came_table, 0u);
    core::CountInChunks(pool, num_pixels, core::kPixelGrain, overlap_tables.size(), &chunk_tables,
                        overlap_tables.data(), [&](size_t b, size_t e, uint32_t* tables) {
                          uint32_t* both = tables;  // this chunk's overlap counts
                          uint32_t* changed = tables + table;
                          uint32_t* nearer = changed + changed_counts.size();
                          uint32_t* front = nearer + nearer_table;
                          uint32_t* came = front + nearer_table;
                          step_depths(b, e, compare_depth);
                          core::ForEachLabelled(prev + b, cur + b, e - b, [&](size_t j) {
                            const size_t i = b + j;
                            const uint32_t p = prev[i];
                            uint32_t c = cur[i];
                            if ((p | c) == 0) return;
                            // A label without an object is background.
                            if (c > cur_max_label || (!contiguous && label_to_det[c] < 0)) c = 0;
                            prev[i] = c;
                            ++both[p * stride + c];
                            if (!compare_depth) return;
                            changed[p * stride + c] += moved[i] & 1u;
                            nearer[c] += moved[i] >> 1;
                            came[p] += moved[i] >> 1;
                            front[c] += age[i] <= recent;
                          });
                        });
    std::copy(overlap_tables.begin(), overlap_tables.begin() + static_cast<ptrdiff_t>(table),
              counts.begin());
    const auto nearer_begin =
        overlap_tables.begin() + static_cast<ptrdiff_t>(table + changed_counts.size());
    std::copy(overlap_tables.begin() + static_cast<ptrdiff_t>(table), nearer_begin,
              changed_counts.begin());
    nearer_size.assign(nearer_begin, nearer_begin + static_cast<ptrdiff_t>(nearer_table));
    const auto came_begin = overlap_tables.end() - static_cast<ptrdiff_t>(came_table);
    front_size.assign(nearer_begin + static_cast<ptrdiff_t>(nearer_table), came_begin);
    came_size.assign(came_begin, overlap_tables.end());
    moved_size.assign(nearer_table, 0u);
    prev_size.assign(static_cast<size_t>(prev_max_label) + 1, 0u);
    cur_size.assign(stride, 0u);
    changed_size.assign(static_cast<size_t>(prev_max_label) + 1, 0u);
    for (size_t p = 0; p <= prev_max_label; ++p) {
      for (size_t c = 0; c < stride; ++c) {
        const uint32_t n = counts[p * stride + c];
        prev_size[p] += n;
        cur_size[c] += n;
        if (!compare_depth) continue;
        changed_size[p] += changed_counts[p * stride + c];
        moved_size[c] += changed_counts[p * stride + c];
      }
    }
  }
  // A track seen in the previous frame whose surface mostly changed there (hidden behind a new
  // one, or taken away).
  auto surface_changed = [&](const Track& t) {
    return compare_depth && t.prev_label != 0 && prev_size[t.prev_label] > 0 &&
           changed_size[t.prev_label] >= params.surface_change_min_share * prev_size[t.prev_label];
  };
  // ...and whose changed pixels mostly did not come nearer: what it showed was taken away (or
  // went back), not hidden behind a new surface.
  auto taken_away = [&](const Track& t) {
    if (!surface_changed(t)) return false;
    const uint32_t changed = changed_size[t.prev_label];
    return static_cast<float>(changed - came_size[t.prev_label]) >=
           params.part_min_fraction * static_cast<float>(changed);
  };
  // A track seen in the previous frame whose pixels are mostly on no object now (hidden behind
  // something not segmented, or an end of it gone under an occluder sweeping across it).
  auto vanished = [&](const Track& t) {
    return overlap && t.prev_label != 0 && prev_size[t.prev_label] > 0 &&
           counts[t.prev_label * stride] >= params.part_min_fraction * prev_size[t.prev_label];
  };
  // With depth: how much of each remembered track's surface every object shows; also of a
  // track seen in the previous frame whose surface changed or vanished (an occluder crossing it
  // may leave in view a piece of it its previous mask does not reach).
  shown.assign(with_depth ? tracks.size() * static_cast<size_t>(num_dets) : 0, 0u);
  for (size_t r = 0; r < shown.size() / std::max(num_dets, 1); ++r) {
    const Track& t = tracks[r];
    if (have_prev && t.last_seq == prev_seq && !surface_changed(t) && !vanished(t)) continue;
    const uint32_t* cur = frame.labels.data.data();
    for (size_t k = 0; k < t.remembered_pixels.size(); ++k) {
      const uint32_t i = t.remembered_pixels[k];
      const uint32_t c = i < num_pixels ? cur[i] : 0;
      if (c == 0 || c > cur_max_label || label_to_det[c] < 0) continue;
      if (std::fabs(cloud.xyz[i].z - t.remembered_z[k]) <= band.BandAt(t.remembered_z[k])) {
        ++shown[r * static_cast<size_t>(num_dets) + static_cast<size_t>(label_to_det[c])];
      }
    }
  }
  // Object d's pixel count.
  auto det_pixel_count = [&](int d) -> uint32_t {
    const Object& o = frame.objects[static_cast<size_t>(d)];
    return overlap ? cur_size[o.id] : o.num_points;
  };

  auto inter = [&](const Track& t, int d) -> uint32_t {
    const uint32_t id = frame.objects[static_cast<size_t>(d)].id;
    if (!overlap || t.prev_label == 0 || id == 0) return 0;  // id 0 would be background
    return counts[t.prev_label * stride + id];
  };
  // Of inter(t, d), the pixels where the track's surface did not change.
  auto unchanged = [&](const Track& t, int d) -> uint32_t {
    const uint32_t i = inter(t, d);
    if (i == 0 || !compare_depth) return i;
    return i - changed_counts[t.prev_label * stride + frame.objects[static_cast<size_t>(d)].id];
  };

  // Whether object d shows track r's remembered surface, at its depth, with most of its pixels;
  // the score of that association.
  auto shows_surface = [&](int r, int d) {
    if (shown.empty() || tracks[static_cast<size_t>(r)].remembered_pixels.empty()) return false;
    const double n = shown[static_cast<size_t>(r) * num_dets + d];
    return n > 0.0 && n >= params.part_min_fraction * det_pixel_count(d);
  };
  auto surface_score = [&](int r, int d) {
    const double n = shown[static_cast<size_t>(r) * num_dets + d];
    const double size = det_pixel_count(d);
    const auto remembered =
        static_cast<double>(tracks[static_cast<size_t>(r)].remembered_pixels.size());
    return params.lost_score_factor * (0.5 * n / size + 0.5 * n / remembered);
  };

  // Association scores, tracks x objects; 0 = not allowed.
  const int num_tracks = static_cast<int>(tracks.size());
  score.assign(static_cast<size_t>(num_tracks) * num_dets, 0.0);
  const double geo_weight = overlap ? 0.5 * (1.0 - params.mask_weight) : 0.5;
  const double mask_weight = overlap ? params.mask_weight : 0.0;
  // Per track seen in the previous frame: it may take an object by its remembered surface alone
  // (its surface changed, or it vanished with no object to continue on by its mask).
  by_surface.assign(static_cast<size_t>(num_tracks), 0);
  for (int r = 0; r < num_tracks; ++r) {
    const Track& t = tracks[static_cast<size_t>(r)];
    const bool was_visible = have_prev && t.last_seq == prev_seq;
    const float track_diag = Diagonal(t.box);
    bool continues = false;  // an object continues it by its mask or centroid
    surface_pair.assign(static_cast<size_t>(num_dets), 0);
    for (int d = 0; d < num_dets; ++d) {
      const Object& o = frame.objects[static_cast<size_t>(d)];
      const Box box{o.aabb_min, o.aabb_max};
      bool allowed = false;
      double s = 0.0;
      if (was_visible) {
        const float dist = Distance(o.centroid, t.centroid);
        bool ok = dist <= params.max_centroid_step_m &&
                  SizesAlike(Diagonal(box), track_diag, params.max_size_ratio);
        // It continues the track unless it reaches the track's mask only where something came
        // in front (an occluder over a track whose pixels mostly fell into holes).
        bool continuing = ok;
        double iou = 0.0;
        if (overlap && t.prev_label != 0) {
          const double i = inter(t, d);
          const double a = prev_size[t.prev_label];
          const double b = cur_size[o.id];
          if (i > 0.0) {
            const double need = params.min_mask_overlap * std::min(a, b);
            ok = ok || i >= need;
            continuing = continuing || (compare_depth && params.occluder_is_not_continuation
                                            ? unchanged(t, d) >= need
                                            : i >= need);
            iou = i / (a + b - i);
          }
        }
        if (ok) {
          const double near = std::max(0.0, 1.0 - dist / params.max_centroid_step_m);
          s = mask_weight * iou + geo_weight * (near + BoxIou(box, t.box));
          allowed = true;
          continues = continues || continuing;
        } else if (shows_surface(r, d)) {  // a piece of a covered track out of its mask's reach
          s = surface_score(r, d);
          allowed = true;
          surface_pair[static_cast<size_t>(d)] = 1;
        }
      } else if (with_depth && !t.remembered_pixels.empty()) {
        // A remembered surface: the object shows it, at its depth, with most of its pixels.
        if (shows_surface(r, d)) {
          s = surface_score(r, d);
          allowed = true;
        }
      } else {
        const float dist = DistanceToBox(o.centroid, t.ref_box);
        const float inside = InsideShare(box, t.ref_box);
        if (dist <= params.reacquire_distance_m && inside >= params.reacquire_min_box_inside) {
          s = params.lost_score_factor *
              (0.5 * (1.0 - dist / params.reacquire_distance_m) + 0.5 * inside);
          allowed = true;
        }
      }
      score[static_cast<size_t>(r) * num_dets + d] = allowed ? std::max(s, kMinScore) : 0.0;
    }
    if (!was_visible || shown.empty()) continue;
    const bool gone = vanished(t);
    by_surface[static_cast<size_t>(r)] = surface_changed(t) || (gone && !continues);
    if (by_surface[static_cast<size_t>(r)] || !gone) continue;
    // A vanished track that an object continues takes no other object by its surface alone.
    for (int d = 0; d < num_dets; ++d) {
      if (surface_pair[static_cast<size_t>(d)]) score[static_cast<size_t>(r) * num_dets + d] = 0.0;
    }
  }

  // An object that shows a remembered track's surface is that track showing again: a track
  // not yet confirmed that began after it was lost (the object, segmented as new in the frames
  // it showed again) does not keep it.
  for (int d = 0; d < num_dets && with_depth; ++d) {
    // The earliest loss among the remembered tracks whose surface object d shows (in id
    // order, leaving out those that a loss before them already rules out).
    int64_t lost_since = std::numeric_limits<int64_t>::max();
    for (int r = 0; r < num_tracks; ++r) {
      const Track& l = tracks[static_cast<size_t>(r)];
      const bool remembered =
          !(have_prev && l.last_seq == prev_seq) && !l.remembered_pixels.empty();
      const bool ruled_out = !l.confirmed && l.first_seq > lost_since;
      if (remembered && !ruled_out && score[static_cast<size_t>(r) * num_dets + d] > 0.0) {
        lost_since = std::min(lost_since, l.last_seq);
      }
    }
    // So for a confirmed track seen in the previous frame that may take an object by its
    // surface alone (its surface changed, or it vanished with nothing to continue on: an
    // occluder sweeping across it hid the end it held) and whose remembered surface the object
    // shows: no track not yet confirmed keeps the object (the other end, which showed again
    // beside the occluder while the track still held the first, and got a track of its own).
    bool hidden_shown = false;
    for (int r = 0; r < num_tracks && !hidden_shown; ++r) {
      const Track& l = tracks[static_cast<size_t>(r)];
      hidden_shown = l.confirmed && by_surface[static_cast<size_t>(r)] && shows_surface(r, d);
    }
    for (int v = 0; v < num_tracks; ++v) {
      const Track& t = tracks[static_cast<size_t>(v)];
      // A track not yet confirmed remembered after a merge (never seen since: the flag is
      // cleared when it is) is one of the tracks showing again, not a new one.
      if (!t.confirmed && !t.absorbed_tentative && (t.first_seq >= lost_since || hidden_shown))
        score[static_cast<size_t>(v) * num_dets + d] = 0.0;
    }
  }
  // A track whose surface mostly changed (hidden behind a new one, or taken away) continues
  // only on what is left of it: an object lying mostly on its unchanged pixels.
  changed_track.assign(static_cast<size_t>(num_tracks), 0);
  if (compare_depth) {
    for (int r = 0; r < num_tracks; ++r) {
      const Track& t = tracks[static_cast<size_t>(r)];
      if (!surface_changed(t)) continue;
      changed_track[static_cast<size_t>(r)] = 1;
      for (int d = 0; d < num_dets; ++d) {
        const uint32_t size = cur_size[frame.objects[static_cast<size_t>(d)].id];
        const uint32_t i = unchanged(t, d);
        if ((i == 0 || i < params.part_min_fraction * size) && !shows_surface(r, d)) {
          score[static_cast<size_t>(r) * num_dets + d] = 0.0;
        }
      }
    }
  }
  // The overlap that makes an object a part of a track, or a track absorbed by an object: the
  // unchanged pixels of a changed track (a surface in front of it is not a part of it).
  auto part_inter = [&](int r, int d) -> uint32_t {
    const Track& t = tracks[static_cast<size_t>(r)];
    return changed_track[static_cast<size_t>(r)] ? unchanged(t, d) : inter(t, d);
  };

  merged_det.assign(static_cast<size_t>(num_dets), 0);
  keep_tentative.assign(static_cast<size_t>(num_tracks), 0);
  merged_now.assign(static_cast<size_t>(num_tracks), 0);
  split_by_size.assign(static_cast<size_t>(num_tracks), 0);
  // Splits: an object lying mostly on a track's previous mask is a part of the track; only
  // the part with the most points keeps it (with split_own_margin_m, the part nearest the
  // track's own centroid, when clearly nearest). Merges: a track whose previous mask lies mostly
  // on one object is absorbed by it; only the largest of those tracks keeps the object (the one
  // clearly most in view, when one is).
  // A part may keep the track by lying nearest its own centroid only when it holds
  // kOwnPartMinShare of the track's own view: a sliver of an object cut in two by one put down
  // across it lies nearer its centroid than either half.
  auto holds_own = [&](const Track& t, const Object& o) {
    return static_cast<float>(o.num_points) >= kOwnPartMinShare * static_cast<float>(t.own_points);
  };
  // Whether object d mostly came in front of what was there within joined_view_frames: put down
  // on a track (or passing in front of it), never a part of the track's own object when a part
  // that stayed where it was (neither came in front nor moved since the previous frame) is there.
  auto came_in_front = [&](int d) {
    if (front_size.empty()) return false;
    const uint32_t id = frame.objects[static_cast<size_t>(d)].id;
    return front_size[id] > 0 && front_size[id] >= params.part_min_fraction * cur_size[id];
  };
  auto stayed = [&](int d) {
    if (front_size.empty()) return false;
    const uint32_t id = frame.objects[static_cast<size_t>(d)].id;
    return !came_in_front(d) && moved_size[id] < params.part_min_fraction * cur_size[id];
  };
  if (overlap) {
    for (int r = 0; r < num_tracks; ++r) {
      const Track& t = tracks[static_cast<size_t>(r)];
      if (t.prev_label == 0) continue;
      auto is_part = [&](int d) {
        const uint32_t i = part_inter(r, d);
        return i > 0 &&
               i >= params.part_min_fraction * cur_size[frame.objects[static_cast<size_t>(d)].id];
      };
      // When a part stayed where it was, the parts that came in front do not keep the track; only
      // for a track older than joined_view_frames (a newcomer's own pixels all came in front) and
      // a part that is not a sliver.
      bool one_stayed = false;
      const bool old = seq - t.first_seq > params.joined_view_frames;
      for (int d = 0; d < num_dets && old && !one_stayed; ++d) {
        one_stayed = is_part(d) && stayed(d) && holds_own(t, frame.objects[static_cast<size_t>(d)]);
      }
      int parts = 0, best = -1;
      for (int d = 0; d < num_dets; ++d) {
        if (!is_part(d)) continue;
        ++parts;
        if (one_stayed && came_in_front(d)) continue;
        const uint32_t i = part_inter(r, d);
        if (best < 0) {
          best = d;
          continue;
        }
        const Object& o = frame.objects[static_cast<size_t>(d)];
        const Object& b = frame.objects[static_cast<size_t>(best)];
        const float near_o = Distance(o.centroid, t.own_centroid);
        const float near_b = Distance(b.centroid, t.own_centroid);
        const float margin = params.split_own_margin_m;
        const bool own = margin > 0.f;
        if (own && near_o + margin < near_b && holds_own(t, o)) {
          best = d;
        } else if ((!own || near_b + margin >= near_o || !holds_own(t, b)) &&
                   (o.num_points > b.num_points ||
                    (o.num_points == b.num_points && i > part_inter(r, best)))) {
          best = d;
        }
      }
      if (parts < 2) continue;
      ++out->counts.splits;
      // Whether the part was chosen as clearly the nearest to the track's own centroid, not
      // by its size alone.
      const float near_best =
          Distance(frame.objects[static_cast<size_t>(best)].centroid, t.own_centroid);
      // Parts that came in front were not candidates and are no rivals.
      bool by_own =
          params.split_own_margin_m > 0.f && holds_own(t, frame.objects[static_cast<size_t>(best)]);
      bool rivals = false;
      for (int d = 0; d < num_dets; ++d) {
        if (d == best || !is_part(d)) continue;
        score[static_cast<size_t>(r) * num_dets + d] = 0.0;
        if (one_stayed && came_in_front(d)) continue;
        rivals = true;
        by_own =
            by_own && near_best + params.split_own_margin_m <
                          Distance(frame.objects[static_cast<size_t>(d)].centroid, t.own_centroid);
      }
      split_by_size[static_cast<size_t>(r)] = rivals && !by_own;
    }
    for (int d = 0; d < num_dets; ++d) {
      int absorbed = 0, best = -1;
      for (int r = 0; r < num_tracks; ++r) {
        const Track& t = tracks[static_cast<size_t>(r)];
        if (t.prev_label == 0) continue;
        const uint32_t i = part_inter(r, d);
        if (i == 0 || i < params.part_min_fraction * prev_size[t.prev_label]) continue;
        ++absorbed;
        if (best < 0) {
          best = r;
          continue;
        }
        const Track& b = tracks[static_cast<size_t>(best)];
        // The track with more than kMergeInViewFactor times the other's pixels in the object
        // (the other mostly hidden: the segment is mostly this one in view); else the larger
        // object: its largest recent view (a track seen partly hidden keeps the size it had),
        // then the larger overlap; the older track on a tie.
        const uint32_t ib = part_inter(best, d);
        const bool more = i > kMergeInViewFactor * ib, less = ib > kMergeInViewFactor * i;
        if (more ||
            (!less && (t.ref_points > b.ref_points || (t.ref_points == b.ref_points && i > ib)))) {
          best = r;
        }
      }
      if (absorbed < 2) continue;
      ++out->counts.merges;
      merged_det[static_cast<size_t>(d)] = 1;
      const uint32_t ib = part_inter(best, d);
      for (int r = 0; r < num_tracks; ++r) {
        const Track& t = tracks[static_cast<size_t>(r)];
        if (r == best || t.prev_label == 0) continue;
        const uint32_t i = part_inter(r, d);
        if (i > 0 && i >= params.part_min_fraction * prev_size[t.prev_label]) {
          score[static_cast<size_t>(r) * num_dets + d] = 0.0;
          if (params.tentative_merge_memory && !t.confirmed && ib <= kMergeInViewFactor * i) {
            keep_tentative[static_cast<size_t>(r)] = 1;
          }
          // Seen for memory_frames: an object the segmentation showed on its own, not a
          // piece split off for a few frames while it was put down.
          if (t.confirmed && t.seen >= params.memory_frames) {
            merged_now[static_cast<size_t>(r)] = 1;
          }
        }
      }
    }
  }

  // An object made mostly of a newcomer: more than kMergeInViewFactor times as many of its
  // pixels came in front of what was there in this frame (an object put down against a
  // track's and segmented with it) as it holds of an old track whose surface stayed. The
  // segment is the newcomer's, as a merge goes to the track clearly most in view; the track is
  // remembered and takes its surface back when it shows apart.
  newcomer_from.assign(static_cast<size_t>(num_dets), -1);
  if (compare_depth && params.newcomer_merge) {
    for (int r = 0; r < num_tracks; ++r) {
      const Track& t = tracks[static_cast<size_t>(r)];
      if (t.prev_label == 0 || !t.confirmed || seq - t.first_seq <= params.joined_view_frames ||
          surface_changed(t)) {
        continue;
      }
      for (int d = 0; d < num_dets; ++d) {
        const uint32_t id = frame.objects[static_cast<size_t>(d)].id;
        double& s = score[static_cast<size_t>(r) * num_dets + d];
        if (s > 0.0 && nearer_size[id] > kMergeInViewFactor * unchanged(t, d)) {
          s = 0.0;
          newcomer_from[static_cast<size_t>(d)] = t.id;
        }
      }
    }
  }

  // An object that continues a confirmed visible track (most of the track's previous mask,
  // lying mostly on it or a merge the track keeps; when the track split, the part nearest its
  // own centroid) is not reacquired by a remembered track.
  if (overlap && params.continuation_before_reacquire) {
    for (int d = 0; d < num_dets; ++d) {
      const uint32_t size = cur_size[frame.objects[static_cast<size_t>(d)].id];
      bool claimed = false;
      for (int r = 0; r < num_tracks && !claimed; ++r) {
        const Track& t = tracks[static_cast<size_t>(r)];
        const uint32_t i = inter(t, d);
        const bool continues = score[static_cast<size_t>(r) * num_dets + d] > 0.0;
        claimed = t.prev_label != 0 && t.confirmed && !split_by_size[static_cast<size_t>(r)] &&
                  continues && i > 0 &&
                  (i >= params.part_min_fraction * size || merged_det[static_cast<size_t>(d)]) &&
                  i >= params.part_min_fraction * prev_size[t.prev_label];
        // What is left of a changed track (its score passed the surface-change rule).
        claimed = claimed || (t.prev_label != 0 && t.confirmed && continues &&
                              changed_track[static_cast<size_t>(r)]);
      }
      if (!claimed) continue;
      for (int r = 0; r < num_tracks; ++r) {
        if (tracks[static_cast<size_t>(r)].prev_label == 0) {
          score[static_cast<size_t>(r) * num_dets + d] = 0.0;
        }
      }
    }
  }

  // One optimal assignment maximising the summed score; pairs of score 0 are not matches.
  cost.resize(score.size());
  for (size_t k = 0; k < score.size(); ++k) cost[k] = -score[k];
  solver.Solve(cost, num_tracks, num_dets, &row_to_col);

  det_track.assign(static_cast<size_t>(num_dets), -1);
  out->objects.resize(static_cast<size_t>(num_dets));
  for (int r = 0; r < num_tracks; ++r) {
    const int d = row_to_col[static_cast<size_t>(r)];
    if (d < 0 || score[static_cast<size_t>(r) * num_dets + d] <= 0.0) {
      row_to_col[static_cast<size_t>(r)] = -1;
      continue;
    }
    det_track[static_cast<size_t>(d)] = r;
  }

  // Whether object `o`, matched to track `r`, holds a remembered track's own last view (a
  // merge that goes on after the frame it began in). Only tracks within their memory count,
  // not those kept past it while hidden: a long-hidden track under an object put down on it
  // would otherwise keep that object's own centroid from ever following it.
  auto HoldsRememberedTrack = [&](const Object& o, int r) {
    const Box box{o.aabb_min, o.aabb_max};
    for (int q = 0; q < num_tracks; ++q) {
      if (q == r || row_to_col[static_cast<size_t>(q)] >= 0) continue;
      const Track& l = tracks[static_cast<size_t>(q)];
      const int memory = MemoryFrames(l);
      if (seq - l.last_seq > memory) continue;
      if (DistanceToBox(l.own_centroid, box) == 0.f) return true;
    }
    return false;
  };

  // Whether at least part_min_fraction of a track's remembered surface is hidden behind
  // something nearer now (`in_view` false), or in view on an object at its remembered depth
  // (`in_view` true: a track absorbed in a merge whose object is still there).
  auto mostly = [&](const Track& t, bool in_view) {
    if (!with_depth || t.remembered_pixels.empty()) return false;
    const uint32_t* cur = frame.labels.data.data();
    uint32_t n = 0;
    for (size_t k = 0; k < t.remembered_pixels.size(); ++k) {
      const uint32_t i = t.remembered_pixels[k];
      if (i >= num_pixels) continue;
      const float z = scene ? scene_z[i] : cloud.xyz[i].z, before = t.remembered_z[k];
      const float step = std::max(params.surface_change_min_step_m, band.BandAt(before));
      n += in_view ? cur[i] != 0 && cur[i] <= cur_max_label && std::fabs(before - z) < step
                   : before - z >= step;
    }
    return static_cast<float>(n) >=
           params.part_min_fraction * static_cast<float>(t.remembered_pixels.size());
  };

  // Update the matched tracks, age the others, end the expired ones.
  kept.clear();
  for (int r = 0; r < num_tracks; ++r) {
    // Moved from: only its surface vectors empty; HoldsRememberedTrack reads the scalars.
    Track t = std::move(tracks[static_cast<size_t>(r)]);
    const int d = row_to_col[static_cast<size_t>(r)];
    if (d >= 0) {
      const Object& o = frame.objects[static_cast<size_t>(d)];
      const bool was_visible = have_prev && t.last_seq == prev_seq;
      // A confirmed track's view made mostly of pixels that were background in the previous
      // frame (a new surface joined to it: an object put down against it) is neither its own
      // view nor its reference view.
      // So is a view whose pixels that came nearer than what the previous frame showed there
      // (an object put down on it, or against it) reach part_min_fraction of the track's own
      // view: an object uncovered by one taken away from it comes from behind.
      const uint32_t nearer = nearer_size.empty() ? 0u : nearer_size[o.id];
      const bool stacked =
          overlap && t.prev_label != 0 && t.confirmed && nearer > 0 &&
          static_cast<float>(nearer) >= params.part_min_fraction * static_cast<float>(t.own_points);
      const bool joined = stacked || (overlap && t.prev_label != 0 && t.confirmed &&
                                      counts[o.id] >= params.part_min_fraction * cur_size[o.id]);
      // A view in which the pixels that were another object's in the previous frame and moved
      // reach part_min_fraction of the track's own view (a surface uncovered behind an object
      // taken away, segmented with a piece of the object behind that showed beside it) is not
      // its reference view, nor for joined_view_frames frames while the view reaches out of
      // the reference box: the piece's track does not take the uncovered size as its own
      // (which would make it keep a merge with the object's larger part).
      if (params.uncovered_view_not_reference && compare_depth && t.prev_label != 0 &&
          t.confirmed) {
        // The view's moved pixels less those that were background or its own.
        const uint32_t uncovered =
            moved_size[o.id] - changed_counts[o.id] - changed_counts[t.prev_label * stride + o.id];
        if (uncovered > 0 && static_cast<float>(uncovered) >=
                                 params.part_min_fraction * static_cast<float>(t.own_points)) {
          t.uncovered_seq = seq;
        }
      }
      const bool uncovered_view =
          t.uncovered_seq >= 0 && seq - t.uncovered_seq <= params.joined_view_frames &&
          InsideShare(Box{o.aabb_min, o.aabb_max}, t.ref_box) < params.part_min_fraction;
      if (joined) {
        t.joined_seq = seq;
        t.stacked_points = stacked ? nearer : 0u;
      }
      // ... nor, for joined_view_frames frames, a view still mostly made of what joined it
      // and reaching out of the track's remembered box (an object uncovered by an occluder
      // that leaves grows back within it).
      // A view that came in front of it stays joined while the view holds the track's own
      // view and part_min_fraction of what came.
      const bool still_joined =
          t.joined_seq >= 0 && seq - t.joined_seq <= params.joined_view_frames &&
          ((static_cast<float>(t.own_points) <=
                (1.f - params.part_min_fraction) * static_cast<float>(o.num_points) &&
            InsideShare(Box{o.aabb_min, o.aabb_max}, t.ref_box) < params.part_min_fraction) ||
           (t.stacked_points > 0 &&
            static_cast<float>(o.num_points) >=
                static_cast<float>(t.own_points) +
                    params.part_min_fraction * static_cast<float>(t.stacked_points)));
      const bool own_view = !joined && !still_joined;
      // What the track's reference view showed was taken away: what is left is its view now,
      // so that the size of what left does not make it keep a merge with a neighbour.
      const bool restart_view = own_view && taken_away(t);
      ++(was_visible ? out->counts.continued : out->counts.reacquired);
      t.last_seq = seq;
      t.absorbed_tentative = false;
      t.merged_away = false;
      ++t.seen;
      t.confirmed = t.confirmed || t.seen >= params.confirm_frames;
      t.prev_label = o.id;
      t.num_points = o.num_points;
      t.centroid = o.centroid;
      t.box = Box{o.aabb_min, o.aabb_max};
      if (params.split_own_margin_m <= 0.f ||
          (own_view && !merged_det[static_cast<size_t>(d)] && !HoldsRememberedTrack(o, r))) {
        t.own_centroid = o.centroid;
        t.own_points = o.num_points;
      }
      t.ref_points *= params.reference_decay;
      if (own_view && !uncovered_view &&
          (restart_view || static_cast<float>(o.num_points) >= t.ref_points)) {
        t.ref_points = static_cast<float>(o.num_points);
        t.ref_box = t.box;
        if (with_depth) to_remember.push_back({kept.size(), d, det_pixel_count(d)});
      }
      ObjectTrack& ot = out->objects[static_cast<size_t>(d)];
      ot.track_id = t.id;
      ot.age_frames = static_cast<int32_t>(seq - t.first_seq);
      ot.seen_frames = t.seen;
      ot.state = t.confirmed ? TrackState::kConfirmed : TrackState::kNew;
      ot.reacquired = !was_visible;
      kept.push_back(std::move(t));
      continue;
    }
    t.prev_label = 0;
    const int64_t since = seq - t.last_seq;
    if (keep_tentative[static_cast<size_t>(r)]) t.absorbed_tentative = true;
    if (merged_now[static_cast<size_t>(r)]) t.merged_away = true;
    const int memory = MemoryFrames(t);
    if (since > memory &&
        !(t.confirmed && since <= params.hidden_memory_frames &&
          (mostly(t, false) || (params.merged_memory && t.merged_away && mostly(t, true))))) {
      out->ended_track_ids.push_back(t.id);
      continue;
    }
    kept.push_back(std::move(t));
  }
  // New tracks for the objects left over, in object order (so ids increase with it).
  for (int d = 0; d < num_dets; ++d) {
    if (det_track[static_cast<size_t>(d)] >= 0) continue;
    const Object& o = frame.objects[static_cast<size_t>(d)];
    Track t;
    t.id = next_id++;
    t.first_seq = t.last_seq = seq;
    t.seen = 1;
    t.confirmed = params.confirm_frames <= 1;
    t.prev_label = o.id;
    t.num_points = o.num_points;
    t.centroid = o.centroid;
    t.box = Box{o.aabb_min, o.aabb_max};
    t.ref_points = static_cast<float>(o.num_points);
    t.ref_box = t.box;
    if (with_depth) to_remember.push_back({kept.size(), d, det_pixel_count(d)});
    t.own_centroid = o.centroid;
    t.own_points = o.num_points;
    t.newcomer_of = newcomer_from[static_cast<size_t>(d)];
    ObjectTrack& ot = out->objects[static_cast<size_t>(d)];
    ot.track_id = t.id;
    ot.age_frames = 0;
    ot.seen_frames = 1;
    ot.state = t.confirmed ? TrackState::kConfirmed : TrackState::kNew;
    ot.reacquired = false;
    ++out->counts.created;
    kept.push_back(std::move(t));
  }
  tracks.swap(kept);
  remember_frame = &frame;
  remember_cloud = cloud;

  for (const Track& t : tracks) {
    if (t.last_seq == seq) continue;
    LostTrack& l = out->lost.emplace_back();
    l.track_id = t.id;
    l.frames_since_seen = static_cast<int32_t>(seq - t.last_seq);
    l.age_frames = static_cast<int32_t>(seq - t.first_seq);
    l.seen_frames = t.seen;
    l.state = TrackState::kLost;
    l.was_confirmed = t.confirmed;
    l.num_points = t.num_points;
    l.centroid = t.centroid;
    l.aabb_min = t.box.min;
    l.aabb_max = t.box.max;
    l.remembered_min = t.ref_box.min;
    l.remembered_max = t.ref_box.max;
  }

  if (!overlap) {
    prev_labels.resize(num_pixels);
    for (size_t i = 0; i < num_pixels; ++i) {
      const uint32_t c = frame.labels.data[i];
      prev_labels[i] = c <= cur_max_label && label_to_det[c] >= 0 ? c : 0;
    }
    if (with_depth) depth_changed.resize(num_pixels);
    step_depths(0, num_pixels, false);  // this frame's depths for the next one
  }
  prev_max_label = cur_max_label;
  prev_width = frame.labels.width;
  prev_height = frame.labels.height;
  prev_seq = seq;
  have_prev = true;
}

void Tracker::Impl::RememberSurfaces() {
  if (remember_frame == nullptr) return;
  const SegmentationResult& frame = *remember_frame;
  for (const SurfaceToRemember& r : to_remember) {
    RememberSurface(frame, frame.objects[static_cast<size_t>(r.det)], r.num_pixels, remember_cloud,
                    &tracks[r.track]);
  }
  // A track begun on a newcomer's segment leaves out of its remembered surface what the track
  // it joined remembers, until that one is seen again or ends.
  for (Track& t : tracks) {
    if (t.newcomer_of < 0) continue;
    const auto old = std::find_if(tracks.begin(), tracks.end(),
                                  [&](const Track& o) { return o.id == t.newcomer_of; });
    if (old == tracks.end()) {
      t.newcomer_of = -1;
      continue;
    }
    LeaveOutSurface(*old, &t);
    if (old->last_seq == prev_seq) t.newcomer_of = -1;
  }
  remember_frame = nullptr;
  remember_cloud = {};
}

Tracker::Tracker(const TrackerParams& params, const TemporalFilterParams& band,
                 core::ThreadPool* pool)
    : impl_(std::make_unique<Impl>(params, band, pool)) {}
Tracker::~Tracker() = default;

void Tracker::Update(const SegmentationResult& frame, int64_t frame_seq, TrackingResult* out,
                     const core::PointCloudView& cloud, std::span<const float> scene_z) {
  Associate(frame, frame_seq, out, cloud, scene_z);
  const auto t0 = std::chrono::steady_clock::now();
  impl_->RememberSurfaces();
  out->time_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Tracker::Associate(const SegmentationResult& frame, int64_t frame_seq, TrackingResult* out,
                        const core::PointCloudView& cloud, std::span<const float> scene_z) {
  const auto t0 = std::chrono::steady_clock::now();
  impl_->Associate(frame, frame_seq, out, cloud, scene_z);
  out->time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Tracker::RememberSurfaces() { impl_->RememberSurfaces(); }

void Tracker::Reset() { impl_->reset_pending = true; }

void Tracker::SetParams(const TrackerParams& params) {
  params.ValidateOrThrow();
  impl_->params = params;
}

void Tracker::SetBand(const TemporalFilterParams& band) {
  band.ValidateOrThrow();
  impl_->band = band;
}

const TrackerParams& Tracker::params() const { return impl_->params; }

int64_t Tracker::next_track_id() const { return impl_->next_id; }

}  // namespace clutterseg::pipeline
