#include "clutterseg/pipeline/tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

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

float Distance(const core::Vec3f& a, const core::Vec3f& b) {
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

float Diagonal(const Box& b) { return Distance(b.min, b.max); }

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
  check.InRange("mask_weight", mask_weight, 0.f, 1.f);
  check.Require(lost_score_factor > 0.f && lost_score_factor <= 1.f, "lost_score_factor",
                lost_score_factor, "a factor in (0, 1]");
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
    core::Vec3f own_centroid;  // of its last view that held no other track
  };

  explicit Impl(const TrackerParams& p) : params(p) { params.ValidateOrThrow(); }

  void EndAll(TrackingResult* out) {
    for (const Track& t : tracks) out->ended_track_ids.push_back(t.id);
    tracks.clear();
    have_prev = false;
    prev_labels.clear();
  }

  void Update(const SegmentationResult& frame, int64_t seq, TrackingResult* out);

  TrackerParams params;
  std::vector<Track> tracks;  // by increasing id
  int64_t next_id{1};
  bool have_prev{false};      // a previous frame exists (prev_seq valid)
  bool reset_pending{false};  // Reset() was called since the last Update
  int64_t prev_seq{0};
  int prev_width{0}, prev_height{0};
  std::vector<uint32_t> prev_labels;
  uint32_t prev_max_label{0};

  // Per-frame work buffers.
  std::vector<int32_t> label_to_det;
  std::vector<uint32_t> counts;  // (prev label) x (current label) pixel contingency
  std::vector<uint32_t> prev_size, cur_size;
  std::vector<double> score, cost;
  std::vector<int32_t> row_to_col, det_track;
  std::vector<uint8_t> merged_det;
  std::vector<uint8_t> split_by_size;
  std::vector<Track> kept;
  optimize::AssignmentSolver solver;
};

void Tracker::Impl::Update(const SegmentationResult& frame, int64_t seq, TrackingResult* out) {
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
  if (overlap) {
    counts.assign((static_cast<size_t>(prev_max_label) + 1) * stride, 0u);
    // One pass counts the overlap and keeps this frame's labels for the next one. Most
    // pixels are background in both frames: blocks of 8 such pixels are skipped at once.
    uint32_t* prev = prev_labels.data();
    const uint32_t* cur = frame.labels.data.data();
    const bool contiguous = ids_contiguous;
    auto visit = [&](size_t i) {
      const uint32_t p = prev[i];
      uint32_t c = cur[i];
      if ((p | c) == 0) return;
      // A label without an object is background.
      if (c > cur_max_label || (!contiguous && label_to_det[c] < 0)) c = 0;
      prev[i] = c;
      ++counts[p * stride + c];
    };
    size_t i = 0;
    for (; i + 8 <= num_pixels; i += 8) {
      uint64_t a[4], b[4];
      std::memcpy(a, prev + i, sizeof(a));
      std::memcpy(b, cur + i, sizeof(b));
      if (((a[0] | b[0]) | (a[1] | b[1]) | (a[2] | b[2]) | (a[3] | b[3])) == 0) continue;
      for (size_t j = i; j < i + 8; ++j) visit(j);
    }
    for (; i < num_pixels; ++i) visit(i);
    prev_size.assign(static_cast<size_t>(prev_max_label) + 1, 0u);
    cur_size.assign(stride, 0u);
    for (size_t p = 0; p <= prev_max_label; ++p) {
      for (size_t c = 0; c < stride; ++c) {
        const uint32_t n = counts[p * stride + c];
        prev_size[p] += n;
        cur_size[c] += n;
      }
    }
  }
  auto inter = [&](const Track& t, int d) -> uint32_t {
    const uint32_t id = frame.objects[static_cast<size_t>(d)].id;
    if (!overlap || t.prev_label == 0 || id == 0) return 0;  // id 0 would be background
    return counts[t.prev_label * stride + id];
  };

  // Association scores, tracks x objects; 0 = not allowed.
  const int num_tracks = static_cast<int>(tracks.size());
  score.assign(static_cast<size_t>(num_tracks) * num_dets, 0.0);
  const double geo_weight = overlap ? 0.5 * (1.0 - params.mask_weight) : 0.5;
  const double mask_weight = overlap ? params.mask_weight : 0.0;
  for (int r = 0; r < num_tracks; ++r) {
    const Track& t = tracks[static_cast<size_t>(r)];
    const bool was_visible = have_prev && t.last_seq == prev_seq;
    const float track_diag = Diagonal(t.box);
    for (int d = 0; d < num_dets; ++d) {
      const Object& o = frame.objects[static_cast<size_t>(d)];
      const Box box{o.aabb_min, o.aabb_max};
      bool allowed = false;
      double s = 0.0;
      if (was_visible) {
        const float dist = Distance(o.centroid, t.centroid);
        bool ok = dist <= params.max_centroid_step_m &&
                  SizesAlike(Diagonal(box), track_diag, params.max_size_ratio);
        double iou = 0.0;
        if (overlap && t.prev_label != 0) {
          const double i = inter(t, d);
          const double a = prev_size[t.prev_label];
          const double b = cur_size[o.id];
          if (i > 0.0) {
            ok = ok || i >= params.min_mask_overlap * std::min(a, b);
            iou = i / (a + b - i);
          }
        }
        if (ok) {
          const double near = std::max(0.0, 1.0 - dist / params.max_centroid_step_m);
          s = mask_weight * iou + geo_weight * (near + BoxIou(box, t.box));
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
  }

  merged_det.assign(static_cast<size_t>(num_dets), 0);
  split_by_size.assign(static_cast<size_t>(num_tracks), 0);
  // Splits: an object lying mostly on a track's previous mask is a part of the track; only
  // the part with the most points keeps it (with split_own_margin_m, the part nearest the
  // track's own centroid, when clearly nearest). Merges: a track whose previous mask lies mostly
  // on one object is absorbed by it; only the largest of those tracks keeps the object.
  if (overlap) {
    for (int r = 0; r < num_tracks; ++r) {
      const Track& t = tracks[static_cast<size_t>(r)];
      if (t.prev_label == 0) continue;
      int parts = 0, best = -1;
      for (int d = 0; d < num_dets; ++d) {
        const uint32_t i = inter(t, d);
        const uint32_t size = cur_size[frame.objects[static_cast<size_t>(d)].id];
        if (i == 0 || i < params.part_min_fraction * size) continue;
        ++parts;
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
        if (own && near_o + margin < near_b) {
          best = d;
        } else if ((!own || near_b + margin >= near_o) &&
                   (o.num_points > b.num_points ||
                    (o.num_points == b.num_points && i > inter(t, best)))) {
          best = d;
        }
      }
      if (parts < 2) continue;
      ++out->counts.splits;
      // Whether the part was chosen as clearly the nearest to the track's own centroid, not
      // by its size alone.
      const float near_best =
          Distance(frame.objects[static_cast<size_t>(best)].centroid, t.own_centroid);
      bool by_own = params.split_own_margin_m > 0.f;
      for (int d = 0; d < num_dets; ++d) {
        const uint32_t i = inter(t, d);
        const uint32_t size = cur_size[frame.objects[static_cast<size_t>(d)].id];
        if (d != best && i > 0 && i >= params.part_min_fraction * size) {
          score[static_cast<size_t>(r) * num_dets + d] = 0.0;
          by_own = by_own &&
                   near_best + params.split_own_margin_m <
                       Distance(frame.objects[static_cast<size_t>(d)].centroid, t.own_centroid);
        }
      }
      split_by_size[static_cast<size_t>(r)] = !by_own;
    }
    for (int d = 0; d < num_dets; ++d) {
      int absorbed = 0, best = -1;
      for (int r = 0; r < num_tracks; ++r) {
        const Track& t = tracks[static_cast<size_t>(r)];
        if (t.prev_label == 0) continue;
        const uint32_t i = inter(t, d);
        if (i == 0 || i < params.part_min_fraction * prev_size[t.prev_label]) continue;
        ++absorbed;
        if (best < 0) {
          best = r;
          continue;
        }
        const Track& b = tracks[static_cast<size_t>(best)];
        // The larger object: its largest recent view (a track seen partly hidden keeps the
        // size it had), then the larger overlap; the older track on a tie.
        const uint32_t ib = inter(b, d);
        if (t.ref_points > b.ref_points || (t.ref_points == b.ref_points && i > ib)) best = r;
      }
      if (absorbed < 2) continue;
      ++out->counts.merges;
      merged_det[static_cast<size_t>(d)] = 1;
      for (int r = 0; r < num_tracks; ++r) {
        const Track& t = tracks[static_cast<size_t>(r)];
        if (r == best || t.prev_label == 0) continue;
        const uint32_t i = inter(t, d);
        if (i > 0 && i >= params.part_min_fraction * prev_size[t.prev_label]) {
          score[static_cast<size_t>(r) * num_dets + d] = 0.0;
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
        claimed = t.prev_label != 0 && t.confirmed && !split_by_size[static_cast<size_t>(r)] &&
                  score[static_cast<size_t>(r) * num_dets + d] > 0.0 && i > 0 &&
                  (i >= params.part_min_fraction * size || merged_det[static_cast<size_t>(d)]) &&
                  i >= params.part_min_fraction * prev_size[t.prev_label];
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
  // merge that goes on after the frame it began in).
  auto HoldsRememberedTrack = [&](const Object& o, int r) {
    const Box box{o.aabb_min, o.aabb_max};
    for (int q = 0; q < num_tracks; ++q) {
      if (q == r || row_to_col[static_cast<size_t>(q)] >= 0) continue;
      const Track& l = tracks[static_cast<size_t>(q)];
      const int memory = l.confirmed ? params.memory_frames : params.tentative_memory_frames;
      if (seq - l.last_seq > memory) continue;
      if (DistanceToBox(l.own_centroid, box) == 0.f) return true;
    }
    return false;
  };

  // Update the matched tracks, age the others, end the expired ones.
  kept.clear();
  for (int r = 0; r < num_tracks; ++r) {
    Track t = tracks[static_cast<size_t>(r)];
    const int d = row_to_col[static_cast<size_t>(r)];
    if (d >= 0) {
      const Object& o = frame.objects[static_cast<size_t>(d)];
      const bool was_visible = have_prev && t.last_seq == prev_seq;
      ++(was_visible ? out->counts.continued : out->counts.reacquired);
      t.last_seq = seq;
      ++t.seen;
      t.confirmed = t.confirmed || t.seen >= params.confirm_frames;
      t.prev_label = o.id;
      t.num_points = o.num_points;
      t.centroid = o.centroid;
      t.box = Box{o.aabb_min, o.aabb_max};
      if (params.split_own_margin_m <= 0.f ||
          (!merged_det[static_cast<size_t>(d)] && !HoldsRememberedTrack(o, r))) {
        t.own_centroid = o.centroid;
      }
      t.ref_points *= params.reference_decay;
      if (static_cast<float>(o.num_points) >= t.ref_points) {
        t.ref_points = static_cast<float>(o.num_points);
        t.ref_box = t.box;
      }
      ObjectTrack& ot = out->objects[static_cast<size_t>(d)];
      ot.track_id = t.id;
      ot.age_frames = static_cast<int32_t>(seq - t.first_seq);
      ot.seen_frames = t.seen;
      ot.state = t.confirmed ? TrackState::kConfirmed : TrackState::kNew;
      ot.reacquired = !was_visible;
      kept.push_back(t);
      continue;
    }
    t.prev_label = 0;
    const int64_t since = seq - t.last_seq;
    const int memory = t.confirmed ? params.memory_frames : params.tentative_memory_frames;
    if (since > memory) {
      out->ended_track_ids.push_back(t.id);
      continue;
    }
    kept.push_back(t);
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
    t.own_centroid = o.centroid;
    ObjectTrack& ot = out->objects[static_cast<size_t>(d)];
    ot.track_id = t.id;
    ot.age_frames = 0;
    ot.seen_frames = 1;
    ot.state = t.confirmed ? TrackState::kConfirmed : TrackState::kNew;
    ot.reacquired = false;
    ++out->counts.created;
    kept.push_back(t);
  }
  tracks.swap(kept);

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
  }
  prev_max_label = cur_max_label;
  prev_width = frame.labels.width;
  prev_height = frame.labels.height;
  prev_seq = seq;
  have_prev = true;
}

Tracker::Tracker(const TrackerParams& params) : impl_(std::make_unique<Impl>(params)) {}
Tracker::~Tracker() = default;

void Tracker::Update(const SegmentationResult& frame, int64_t frame_seq, TrackingResult* out) {
  const auto t0 = std::chrono::steady_clock::now();
  impl_->Update(frame, frame_seq, out);
  out->time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Tracker::Reset() { impl_->reset_pending = true; }

void Tracker::SetParams(const TrackerParams& params) {
  params.ValidateOrThrow();
  impl_->params = params;
}

const TrackerParams& Tracker::params() const { return impl_->params; }

int64_t Tracker::next_track_id() const { return impl_->next_id; }

}  // namespace clutterseg::pipeline
