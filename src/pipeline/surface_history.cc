#include "clutterseg/pipeline/surface_history.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "clutterseg/core/label_scan.h"
#include "clutterseg/core/union_find.h"
#include "clutterseg/pipeline/partition_prior.h"

namespace clutterseg::pipeline {
namespace {

constexpr uint8_t kRefKnown = 1;  // the surface's arrival is known
constexpr uint8_t kOldKnown = 2;  // the previous surface's arrival is known
constexpr uint8_t kOnCand = 4;    // the last measurement was a candidate, not the surface
constexpr uint8_t kDirect = 8;    // the candidate began right after the surface was measured
// Whether the surface was in a segment or in none (the support, the background) in the first
// frame it was labelled, and the same for the previous surface.
constexpr uint8_t kRefSeen = 16;
constexpr uint8_t kRefBackground = 32;
constexpr uint8_t kOldSeen = 64;
constexpr uint8_t kOldBackground = 128;
constexpr uint8_t kRefClass = kRefSeen | kRefBackground;
constexpr uint8_t kOldClass = kOldSeen | kOldBackground;

// Whether a pixel of these flags has an arrival (SurfaceHistory::Arrival).
constexpr bool ArrivalKnown(uint8_t f) {
  return (f & (kRefKnown | kOnCand | kRefBackground)) == kRefKnown;
}

// Arrivals of fewer pixels than this (or than 0.5 % of a segment's) are scattered noise.
constexpr uint32_t kMinArrivalPixels = 5;
// Passes of FillFromNeighbours; pixels still unreached after them keep their segment's label.
constexpr int kMaxFillPasses = 64;
constexpr int kMovedRadius = 2;  // pixels around an uncovered pixel that are "next to" it
// Two pixels of neighbouring segments touch when their depths are within this many depth
// bands of each other (a steep face seen at a grazing angle steps by more than one).
constexpr float kRejoinBands = 2.f;
// Pieces of one arrival touch when they are 4-neighbours in the image or at most this many
// unlabelled pixels apart along a row or a column, at any depth: a cup's inside and its outside
// wall are separated by the rim, seen edge-on, and its shadow (a few pixels) and a depth step
// of up to the vessel's diameter.
constexpr int kJoinGapPixels = 6;
// Pieces of one arrival also touch across something in front of both (an object put down
// across one lying there hides its middle; the ends stay in view), at most this many pixels
// wide, holes included; this many such pairs join them.
constexpr int kBridgePixels = 64;
constexpr uint32_t kBridgeMinContact = 10;
// Pieces of one arrival are of one object put down when most of their pixels arrived within
// this many frames of each other: an object put down shows all of its faces in the frame it
// comes to rest, while objects put down one after another arrive frames apart.
constexpr int32_t kJoinMaxPeakFrames = 0;
// A frame in which more than a quarter of the pixels left their surface is a new view (the
// camera moved): what arrived then arrived with everything in view. The last this many are
// remembered.
constexpr size_t kMaxNewViews = 1024;

// The common steps of SurfaceHistory::Update, for every pixel at once: a pixel within the band
// of its surface (settled) and, with kCandidates, a candidate begun or continued but not
// confirmed (a new depth in front of or behind the surface). Each applies the same rule as
// Update; all other pixels with a valid depth are marked in `todo` and left unchanged, so the
// two variants give the same state after Update. Returns the number of valid pixels not
// settled. Written without branches (conditions as all-ones or all-zero masks of the lane's
// width, combined with bitwise operators and selects; no multiplications, which SSE2 has only
// as a sequence of shuffles for 32-bit lanes) and with restrict pointers, so the compiler
// vectorises it; the variant without candidates moves half the bytes per pixel.
template <bool kCandidates>
uint32_t StepWithoutBranches(size_t num, const float* __restrict zs,
                             const TemporalFilterParams band_params, int32_t now, int32_t confirm,
                             const float* __restrict old_z, float* __restrict ref_z,
                             float* __restrict cand_z, int32_t* __restrict cand_since,
                             uint8_t* __restrict cand_n, uint8_t* __restrict flags,
                             uint8_t* __restrict todo) {
  // a where the mask m is all ones, else b.
  const auto pick = [](int32_t m, int32_t a, int32_t b) { return (m & a) | (~m & b); };
  uint32_t changed = 0;
  for (size_t i = 0; i < num; ++i) {
    const float z = zs[i], r = ref_z[i];
    const int32_t f = flags[i], n = cand_n[i];
    const float band = band_params.BandAt(z);  // by value: no reload per pixel
    const int32_t valid = z > 0.f;
    const int32_t settled = valid & (std::abs(z - r) <= band);  // false for a NaN r
    const int32_t settled_m = -settled;
    ref_z[i] = settled ? z : r;
    changed += static_cast<uint32_t>(valid & (settled ^ 1));
    if constexpr (kCandidates) {
      const float c = cand_z[i];
      const int32_t first = r != r;                         // no surface yet
      const int32_t back = std::abs(z - old_z[i]) <= band;  // false for a NaN old_z
      const int32_t on_cand = (f & kOnCand) >> 2;
      const int32_t cont = on_cand & (std::abs(z - c) <= band);
      const int32_t n_next = pick(-cont, n + (n < 255), 1);
      const int32_t step = valid & (settled ^ 1) & (first ^ 1) & (back ^ 1) & (n_next < confirm);
      const int32_t step_m = -step;
      const int32_t fresh_m = -(step & (cont ^ 1));  // a new candidate, direct after the surface
      const int32_t fresh_f = (f & ~kDirect) | kOnCand | ((on_cand - 1) & kDirect);
      cand_z[i] = step ? z : c;
      cand_since[i] = pick(fresh_m, now, cand_since[i]);
      cand_n[i] = static_cast<uint8_t>(pick(step_m, n_next, n) & ~settled_m);
      flags[i] = static_cast<uint8_t>(pick(fresh_m, fresh_f, f) & ~(settled_m & kOnCand));
      todo[i] = static_cast<uint8_t>(valid & (settled ^ 1) & (step ^ 1));
    } else {
      cand_n[i] = static_cast<uint8_t>(n & ~settled_m);
      flags[i] = static_cast<uint8_t>(f & ~(settled_m & kOnCand));
      todo[i] = static_cast<uint8_t>(valid & (settled ^ 1));
    }
  }
  return changed;
}

// Marks the surfaces labelled for the first time (not on a candidate, a depth known): seen in
// a segment (a label 1..n) or as the support (any other label). Without branches, vectorised.
void MarkFirstLabelled(size_t num, const uint32_t* __restrict labels, uint32_t n,
                       const float* __restrict ref_z, uint8_t* __restrict flags) {
  for (size_t i = 0; i < num; ++i) {
    const uint32_t f = flags[i], r = labels[i];
    const uint32_t first = ((f & (kRefSeen | kOnCand)) == 0) & (ref_z[i] == ref_z[i]);
    const uint32_t background = (r == 0) | (r > n);
    flags[i] = static_cast<uint8_t>(f | first * (kRefSeen | background * kRefBackground));
  }
}

}  // namespace

void FillFromNeighbours(const uint32_t* in, int w, int h, std::vector<uint32_t>* pending,
                        std::vector<uint32_t>* pending_next, std::vector<uint32_t>* taken,
                        uint32_t* out) {
  for (int pass = 0; pass < kMaxFillPasses && !pending->empty(); ++pass) {
    pending_next->clear();
    taken->clear();
    for (const uint32_t i : *pending) {
      const uint32_t r = in[i];
      const int u = static_cast<int>(i % static_cast<size_t>(w));
      const int v = static_cast<int>(i / static_cast<size_t>(w));
      uint32_t take = 0;
      const auto look = [&](int uu, int vv) {
        if (take != 0 || uu < 0 || vv < 0 || uu >= w || vv >= h) return;
        const size_t j = static_cast<size_t>(vv) * static_cast<size_t>(w) + static_cast<size_t>(uu);
        if (in[j] == r && out[j] != 0) take = out[j];
      };
      look(u - 1, v);
      look(u + 1, v);
      look(u, v - 1);
      look(u, v + 1);
      if (take == 0) {
        pending_next->push_back(i);
      } else {
        taken->push_back(i);
        taken->push_back(take);
      }
    }
    if (taken->empty()) break;
    for (size_t k = 0; k < taken->size(); k += 2) out[(*taken)[k]] = (*taken)[k + 1];
    pending->swap(*pending_next);
  }
  for (const uint32_t i : *pending) out[i] = in[i];  // unreached: the segment's own label
}

SurfaceHistory::SurfaceHistory(const PartitionPriorParams& params, const TemporalFilterParams& band,
                               core::ThreadPool* pool)
    : params_{params.arrival_gap_frames,
              params.arrival_confirm_frames,
              params.min_pixels,
              params.arrival_moved_min_pixels,
              params.arrival_rejoin_min_contact,
              params.arrival_join_min_contact,
              params.arrival_min_share},
      band_(band),
      pool_(pool) {}

void SurfaceHistory::Reset() { have_ = false; }

int32_t SurfaceHistory::Arrival(size_t i) const {
  // A pixel on a candidate not yet confirmed has none: a passing occluder or noise. (Counting
  // a candidate in front as arrived at once split stacks up to confirm_frames earlier but lost
  // coverage and switched more ids on the tuning recordings.)
  // Nor does a surface first seen as the background: the support around an object, where the
  // object is within the depth band of the table behind it (the flank of a can lying down).
  return ArrivalKnown(flags_[i]) ? ref_birth_[i] : -1;
}

size_t SurfaceHistory::memory_bytes() const {
  return (ref_z_.capacity() + old_z_.capacity() + cand_z_.capacity()) * sizeof(float) +
         (ref_birth_.capacity() + ref_since_.capacity() + old_birth_.capacity() +
          cand_since_.capacity()) *
             sizeof(int32_t) +
         cand_n_.capacity() + flags_.capacity() + z_.capacity() * sizeof(float) + todo_.capacity() +
         new_views_.capacity() * sizeof(int32_t);
}

void SurfaceHistory::Update(const core::PointCloudView& cloud, std::span<const float> scene_z,
                            int32_t now) {
  const bool scene = scene_z.size() == cloud.size();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  if (!have_ || num_pixels_ != cloud.size()) {
    num_pixels_ = cloud.size();
    ref_z_.assign(num_pixels_, nan);
    old_z_.assign(num_pixels_, nan);
    cand_z_.assign(num_pixels_, nan);
    ref_birth_.assign(num_pixels_, 0);
    ref_since_.assign(num_pixels_, 0);
    old_birth_.assign(num_pixels_, 0);
    cand_since_.assign(num_pixels_, 0);
    cand_n_.assign(num_pixels_, 0);
    flags_.assign(num_pixels_, 0);
    new_views_.clear();
    new_views_dropped_ = false;
  }
  uncovered_.clear();
  uncovered_birth_.clear();
  uncovered_since_.clear();
  // Most pixels show the surface they showed before, or a candidate that is not confirmed
  // this frame: a first pass (StepWithoutBranches) settles them, and leaves the others (a
  // first measurement, the previous surface again, a candidate confirmed) to the rules below.
  const float* zs = scene_z.data();
  if (!scene) {
    z_.resize(num_pixels_);
    for (size_t i = 0; i < num_pixels_; ++i) z_[i] = cloud.xyz[i].z;
    zs = z_.data();
  }
  depth_ = zs;
  todo_.resize(num_pixels_);
  // The candidates' step moves twice the bytes per pixel; it pays where most pixels changed in
  // the previous frame (a new view, a camera carried around).
  // Every pixel on its own: in chunks on the pool, the counts added in chunk order.
  const bool changing = 4 * static_cast<size_t>(last_changed_) > num_pixels_;
  const auto step = changing ? StepWithoutBranches<true> : StepWithoutBranches<false>;
  chunk_changed_.assign(core::ThreadPool::NumChunks(num_pixels_, core::kPixelGrain), 0u);
  core::ForChunks(pool_, num_pixels_, core::kPixelGrain, [&](size_t b, size_t e) {
    chunk_changed_[b / core::kPixelGrain] =
        step(e - b, zs + b, band_, now, params_.confirm_frames, old_z_.data() + b,
             ref_z_.data() + b, cand_z_.data() + b, cand_since_.data() + b, cand_n_.data() + b,
             flags_.data() + b, todo_.data() + b);
  });
  last_changed_ = 0;
  for (const uint32_t c : chunk_changed_) last_changed_ += c;
  if (4 * static_cast<size_t>(last_changed_) > num_pixels_) {
    if (new_views_.size() == kMaxNewViews) {
      new_views_.erase(new_views_.begin());
      new_views_dropped_ = true;
    }
    new_views_.push_back(now);
  }
  const int confirm = params_.confirm_frames;
  for (size_t i = 0; i < num_pixels_; ++i) {
    if (i % 8 == 0 && i + 8 <= num_pixels_) {  // skip eight settled pixels at once
      uint64_t word;
      std::memcpy(&word, todo_.data() + i, sizeof(word));
      if (word == 0) {
        i += 7;
        continue;
      }
    }
    if (!todo_[i]) continue;
    const float z = zs[i];
    uint8_t& f = flags_[i];
    if (std::isnan(ref_z_[i])) {
      // First measurement: arrived now (in the first frame: there from the start). A pixel
      // that was a hole until something came in range in front of the camera saw it arrive.
      ref_z_[i] = z;
      ref_birth_[i] = ref_since_[i] = now;
      f = kRefKnown;
      continue;
    }
    const float band = band_.BandAt(z);
    if (!std::isnan(old_z_[i]) && std::abs(z - old_z_[i]) <= band) {
      // The previous surface again (an occluder left, a covering object was taken away): it
      // keeps its arrival; the surface it replaces becomes the previous one.
      std::swap(ref_z_[i], old_z_[i]);
      std::swap(ref_birth_[i], old_birth_[i]);
      ref_z_[i] = z;
      ref_since_[i] = now;
      const uint8_t ref_known = (f & kOldKnown) ? kRefKnown : 0;
      const uint8_t old_known = (f & kRefKnown) ? kOldKnown : 0;
      f = static_cast<uint8_t>(ref_known | old_known | ((f & kOldClass) >> 2) |
                               ((f & kRefClass) << 2));
      cand_n_[i] = 0;
      continue;
    }
    if ((f & kOnCand) && std::abs(z - cand_z_[i]) <= band) {
      cand_z_[i] = z;
      if (cand_n_[i] < 255) ++cand_n_[i];
    } else {
      // A new candidate: direct when the pixel showed its surface (or a hole) just before.
      const bool direct = (f & kOnCand) == 0;
      cand_z_[i] = z;
      cand_since_[i] = now;
      cand_n_[i] = 1;
      f = static_cast<uint8_t>((f & ~kDirect) | kOnCand | (direct ? kDirect : 0));
    }
    if (cand_n_[i] < confirm) continue;
    // The candidate is the pixel's surface now. Something put down in front of the surface
    // arrived at the candidate's first frame; a surface behind it was uncovered.
    const bool closer = z < ref_z_[i];
    if (!closer && (f & kRefKnown)) {
      uncovered_.push_back(static_cast<uint32_t>(i));
      uncovered_birth_.push_back(ref_birth_[i]);
      uncovered_since_.push_back(cand_since_[i]);
    }
    uint8_t nf = (closer && (f & kDirect)) ? kRefKnown : 0;
    if (now - ref_since_[i] >= params_.gap_frames) {  // a lasting surface is remembered
      old_z_[i] = ref_z_[i];
      old_birth_[i] = ref_birth_[i];
      if (f & kRefKnown) nf |= kOldKnown;
      nf |= static_cast<uint8_t>((f & kRefClass) << 2);
    } else {
      nf |= f & (kOldKnown | kOldClass);
    }
    ref_z_[i] = z;
    ref_birth_[i] = ref_since_[i] = cand_since_[i];
    cand_n_[i] = 0;
    f = nf;
  }
}

void SurfaceHistory::ApplyMoves(const uint32_t* labels, uint32_t n, int w, int h) {
  moved_.clear();
  for (size_t k = 0; k < uncovered_.size(); ++k) {
    const int u = static_cast<int>(uncovered_[k] % static_cast<uint32_t>(w));
    const int v = static_cast<int>(uncovered_[k] / static_cast<uint32_t>(w));
    // Each segment next to this pixel counts it once.
    uint32_t seen[(2 * kMovedRadius + 1) * (2 * kMovedRadius + 1)];
    int num_seen = 0;
    for (int dv = -kMovedRadius; dv <= kMovedRadius; ++dv) {
      for (int du = -kMovedRadius; du <= kMovedRadius; ++du) {
        const int uu = u + du, vv = v + dv;
        if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
        const uint32_t l =
            labels[static_cast<size_t>(vv) * static_cast<size_t>(w) + static_cast<size_t>(uu)];
        if (l == 0 || l > n || std::find(seen, seen + num_seen, l) != seen + num_seen) continue;
        seen[num_seen++] = l;
        const int32_t b = uncovered_birth_[k];
        auto it = std::find_if(moved_.begin(), moved_.end(), [&](const Moved& m) {
          return m.label == l && std::abs(m.birth - b) <= params_.gap_frames;
        });
        if (it == moved_.end()) {
          moved_.push_back(Moved{l, b, uncovered_since_[k], 1});
        } else {
          ++it->count;
          it->since = std::max(it->since, uncovered_since_[k]);
        }
      }
    }
  }
  num_moved_ = 0;
  const auto min_count = static_cast<uint32_t>(params_.moved_min_pixels);
  moved_.erase(std::remove_if(moved_.begin(), moved_.end(),
                              [&](const Moved& m) { return m.count < min_count; }),
               moved_.end());
  if (moved_.empty()) return;
  num_moved_ = static_cast<int>(moved_.size());
  for (size_t i = 0; i < num_pixels_; ++i) {
    const uint32_t l = labels[i];
    if (l == 0 || l > n || !(flags_[i] & kRefKnown)) continue;
    for (const Moved& m : moved_) {
      if (m.label == l && std::abs(ref_birth_[i] - m.birth) <= params_.gap_frames) {
        ref_birth_[i] = std::max(ref_birth_[i], m.since);
      }
    }
  }
}

uint32_t SurfaceHistory::Apply(const core::PointCloudView& cloud, std::span<const float> scene_z,
                               int64_t seq, uint32_t n, uint32_t* labels) {
  num_split_ = 0;
  num_moved_ = 0;
  num_joined_ = 0;
  if (!have_) base_seq_ = seq;
  const int64_t rel = std::clamp<int64_t>(seq - base_seq_, 0, std::numeric_limits<int32_t>::max());
  const int32_t now = static_cast<int32_t>(rel);
  changed_ = false;
  if (params_.gap_frames <= 0) return n;  // off: no state kept
  Update(cloud, scene_z, now);
  have_ = true;
  const int w = cloud.width, h = cloud.height;
  ApplyMoves(labels, n, w, h);

  // Arrivals per segment, with their pixel counts: runs of pixels of one arrival in scan order
  // first (a segment has a few arrivals in long runs), per chunk of pixels on the pool, then
  // merged (sums per arrival: the same whatever the chunks).
  runs_.resize(n + 1);
  for (auto& v : runs_) v.clear();
  {
    const size_t stride = n + 1;
    const size_t chunks = core::ThreadPool::NumChunks(num_pixels_, core::kPixelGrain);
    if (chunk_runs_.size() < chunks * stride) chunk_runs_.resize(chunks * stride);
    const int32_t* birth = ref_birth_.data();
    core::ForChunks(pool_, num_pixels_, core::kPixelGrain, [&](size_t b, size_t e) {
      std::vector<Entry>* runs_of = chunk_runs_.data() + (b / core::kPixelGrain) * stride;
      for (size_t r = 0; r < stride; ++r) runs_of[r].clear();
      MarkFirstLabelled(e - b, labels + b, n, ref_z_.data() + b, flags_.data() + b);
      const uint8_t* flags = flags_.data();
      core::ForEachLabelled(labels + b, labels + b, e - b, [&](size_t j) {  // background skipped
        const size_t i = b + j;
        const uint32_t r = labels[i];
        if (r == 0 || r > n || !ArrivalKnown(flags[i])) return;  // Arrival(i) < 0
        std::vector<Entry>& runs = runs_of[r];
        if (!runs.empty() && runs.back().birth == birth[i]) {
          ++runs.back().count;
        } else {
          runs.push_back(Entry{birth[i], 1});
        }
      });
    });
    for (size_t k = 0; k < chunks; ++k) {
      for (uint32_t r = 1; r <= n; ++r) {
        const std::vector<Entry>& c = chunk_runs_[k * stride + r];
        runs_[r].insert(runs_[r].end(), c.begin(), c.end());
      }
    }
  }
  uint32_t next = n + 1;
  entries_.resize(n + 1);
  to_.resize(n + 1);
  lo_.assign(n + 1, -1);
  hi_.assign(n + 1, -1);
  peak_.assign(n + 1, -1);
  part_.assign(n + 1, 0u);
  origin_.resize(n + 1);
  for (uint32_t r = 0; r <= n; ++r) origin_[r] = r;
  bool any = false;
  for (uint32_t r = 1; r <= n; ++r) {
    std::vector<Entry>& es = entries_[r];
    std::vector<uint32_t>& to = to_[r];
    es.clear();
    to.clear();
    std::vector<Entry>& runs = runs_[r];
    uint32_t total = 0;
    for (const Entry& e : runs) total += e.count;
    if (total < static_cast<uint32_t>(params_.min_pixels)) continue;
    std::sort(runs.begin(), runs.end(),
              [](const Entry& a, const Entry& b) { return a.birth < b.birth; });
    for (const Entry& e : runs) {
      if (es.empty() || es.back().birth != e.birth) es.push_back(Entry{e.birth, 0});
      es.back().count += e.count;
    }
    // Groups: the arrivals of more than a few pixels in order, a new group after a gap of more
    // than gap_frames. Scattered arrivals (a pixel's noise now and then measured as a surface
    // in front) neither join groups nor make them; they go to the nearest part.
    const uint32_t significant = std::max<uint32_t>(kMinArrivalPixels, total / 200);
    const auto need = static_cast<uint32_t>(
        std::max<float>(static_cast<float>(params_.min_pixels), params_.min_share * total));
    std::vector<uint32_t>& group_px = group_px_;
    group_px.clear();
    group_lo_.clear();
    group_hi_.clear();
    group_peak_.clear();
    to.assign(es.size(), 0u);
    int32_t last = 0;
    for (size_t k = 0; k < es.size(); ++k) {
      if (es[k].count < significant) continue;
      if (group_px.empty() || es[k].birth - last > params_.gap_frames) {
        group_px.push_back(0);
        group_lo_.push_back(es[k].birth);
        group_hi_.push_back(es[k].birth);
        group_peak_.push_back(k);
      }
      last = es[k].birth;
      to[k] = static_cast<uint32_t>(group_px.size());  // 1-based group
      group_px.back() += es[k].count;
      group_hi_.back() = es[k].birth;
      if (es[k].count > es[group_peak_.back()].count) group_peak_.back() = k;
    }
    int groups = 0;
    size_t largest = 0;
    for (size_t g = 0; g < group_px.size(); ++g) {
      groups += group_px[g] >= need ? 1 : 0;
      if (group_px[g] > group_px[largest]) largest = g;
    }
    if (!group_px.empty()) {  // the segment's own arrival, for parts that may join it
      lo_[r] = group_lo_[largest];
      hi_[r] = group_hi_[largest];
      peak_[r] = es[group_peak_[largest]].birth;
    }
    if (groups < 2) {
      to.clear();
      continue;
    }
    // The first large group keeps the segment's label; small groups go to the nearest part.
    std::vector<uint32_t>& label_of = label_of_;
    label_of.assign(group_px.size() + 1, 0u);
    bool first = true;
    for (size_t g = 0; g < group_px.size(); ++g) {
      if (group_px[g] < need) continue;
      const uint32_t l = first ? r : next++;
      label_of[g + 1] = l;
      first = false;
      if (l >= lo_.size()) {
        lo_.resize(l + 1, -1);
        hi_.resize(l + 1, -1);
        peak_.resize(l + 1, -1);
        part_.resize(l + 1, 0u);
        origin_.resize(l + 1, 0u);
      }
      lo_[l] = group_lo_[g];
      hi_[l] = group_hi_[g];
      peak_[l] = es[group_peak_[g]].birth;
      part_[l] = 1;
      origin_[l] = r;
    }
    for (size_t k = 0; k < es.size(); ++k) to[k] = label_of[to[k]];
    ++num_split_;
    any = true;
  }
  if (!any) {  // nothing split: only the join of one arrival's pieces may change the labels
    if (!MarkTogether(n)) return n;
    Rejoin(cloud, n, labels);
    changed_ = num_joined_ > 0;
    return n;
  }
  changed_ = true;

  out_.resize(num_pixels_);
  pending_.clear();
  for (size_t i = 0; i < num_pixels_; ++i) {
    const uint32_t r = labels[i] <= n ? labels[i] : 0;
    out_[i] = r;
    if (r == 0 || r > n || to_[r].empty()) continue;
    uint32_t o = 0;
    if (const int32_t b = Arrival(i); b >= 0) {
      const std::vector<Entry>& es = entries_[r];
      const auto it = std::lower_bound(es.begin(), es.end(), b,
                                       [](const Entry& e, int32_t x) { return e.birth < x; });
      if (it != es.end() && it->birth == b) o = to_[r][static_cast<size_t>(it - es.begin())];
    }
    out_[i] = o;
    if (o == 0) pending_.push_back(static_cast<uint32_t>(i));
  }
  FillFromNeighbours(labels, w, h, &pending_, &pending_next_, &taken_, out_.data());
  MarkTogether(next - 1);
  Rejoin(cloud, next - 1, out_.data());
  std::copy(out_.begin(), out_.end(), labels);
  return next - 1;
}

bool SurfaceHistory::NewView(int32_t frame) const {
  if (new_views_dropped_ && (new_views_.empty() || frame < new_views_.front())) return true;
  return std::binary_search(new_views_.begin(), new_views_.end(), frame);
}

bool SurfaceHistory::ArrivedTogether(uint32_t a, uint32_t b) const {
  return lo_[a] > 0 && lo_[b] > 0 && std::abs(peak_[a] - peak_[b]) <= kJoinMaxPeakFrames &&
         !NewView(peak_[a]) && !NewView(peak_[b]);
}

bool SurfaceHistory::MarkTogether(uint32_t num_labels) {
  together_.assign(num_labels + 1, 0u);
  if (params_.join_min_contact <= 0) return false;
  bool any = false;
  for (uint32_t a = 1; a <= num_labels; ++a) {
    for (uint32_t b = a + 1; b <= num_labels; ++b) {
      if (!ArrivedTogether(a, b)) continue;
      together_[a] = together_[b] = 1;
      any = true;
    }
  }
  return any;
}

void SurfaceHistory::Rejoin(const core::PointCloudView& cloud, uint32_t num_labels, uint32_t* out) {
  const bool join = params_.join_min_contact > 0;
  if (params_.rejoin_min_contact <= 0 && !join) return;
  const int w = cloud.width, h = cloud.height;
  // Contacts between a part and a segment it was not cut from (with the join, between any two
  // segments not cut apart): pairs of 4-neighbour pixels, or of pixels one unlabelled pixel
  // apart, whose depths lie within kRejoinBands bands (`count`, for the parts), and with the
  // join also pairs up to kJoinGapPixels unlabelled pixels apart at any depth (`wide`).
  contacts_.clear();
  const bool any_part =
      std::any_of(part_.begin(), part_.begin() + num_labels + 1, [](uint8_t p) { return p != 0; });
  const size_t row = static_cast<size_t>(w);
  // The contact of segments a and b (found from the last one added: a scan meets the same pair
  // in runs), a new one when they have none yet.
  const auto contact = [&](uint32_t a, uint32_t b) -> Contact& {
    if (a > b) std::swap(a, b);
    for (auto it = contacts_.rbegin(); it != contacts_.rend(); ++it) {
      if (it->a == a && it->b == b) return *it;
    }
    return contacts_.emplace_back(Contact{a, b, 0u, 0u, 0u});
  };
  const auto touch = [&](size_t i, size_t j, bool adjacent) {
    uint32_t a = out[i], b = out[j];
    if (a == b || a > num_labels || b > num_labels) return;
    const bool parts = part_[a] || part_[b], joins = together_[a] && together_[b];
    if (!parts && !joins) return;
    if (origin_[a] == origin_[b]) return;  // cut apart by their arrivals
    const float za = cloud.xyz[i].z, zb = cloud.xyz[j].z;
    const bool near = parts && adjacent && za > 0.f && zb > 0.f &&
                      std::abs(za - zb) <= kRejoinBands * band_.BandAt(za);
    if (!near && !joins) return;
    Contact& c = contact(a, b);
    c.count += near ? 1u : 0u;
    c.wide += joins ? 1u : 0u;
  };
  // From pixel i of a segment that arrived with others, `step` at a time up to kBridgePixels:
  // over pixels in front of it (of other segments, or unlabelled) and holes, to the first
  // pixel of a segment that is not; a pair when that segment arrived with others too and what
  // lies between is in front of it as well.
  const float* depth = depth_;
  const auto bridge = [&](size_t i, size_t step, int limit) {
    const uint32_t l = out[i];
    const float zi = depth[i];
    if (!(zi > 0.f)) return;
    const float front_of_i = zi - band_.BandAt(zi);
    float deepest = -1.f;  // the deepest pixel in front passed (-1: none yet)
    for (int k = 1; k <= limit; ++k) {
      const size_t j = i + static_cast<size_t>(k) * step;
      const uint32_t lj = out[j];
      const float zj = depth[j];
      if (lj == l) return;
      const bool valid = zj > 0.f;
      if (valid && zj < front_of_i) {
        deepest = std::max(deepest, zj);
        continue;
      }
      if (lj == 0 || lj > num_labels) {
        if (valid) return;  // a surface not in front (the support): a gap, not an occluder
        continue;           // a hole (the occluder's shadow)
      }
      if (deepest < 0.f || !valid || !together_[lj] || origin_[l] == origin_[lj]) return;
      if (deepest >= zj - band_.BandAt(zj)) return;
      ++contact(l, lj).bridged;
      return;
    }
  };
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * static_cast<size_t>(w) + static_cast<size_t>(u);
      const uint32_t l = out[i];
      if (l == 0 || l > num_labels || (!any_part && !together_[l])) continue;
      // Across one unlabelled pixel (a hole or an edge pixel between two segments), and for the
      // join up to kJoinGapPixels.
      const int reach = (together_[l] ? kJoinGapPixels : 1) + 1;
      for (int k = 1; k <= reach && u + k < w; ++k) {
        const size_t j = i + static_cast<size_t>(k);
        if (out[j] == 0) continue;
        touch(i, j, k <= 2);
        break;
      }
      for (int k = 1; k <= reach && v + k < h; ++k) {
        const size_t j = i + static_cast<size_t>(k) * row;
        if (out[j] == 0) continue;
        touch(i, j, k <= 2);
        break;
      }
      if (join && together_[l]) {
        bridge(i, 1, std::min(kBridgePixels, w - 1 - u));
        bridge(i, row, std::min(kBridgePixels, h - 1 - v));
      }
    }
  }
  if (contacts_.empty()) return;
  // Each part joins the neighbour of its arrival it touches most. The first frame's surfaces
  // all arrived together, so their common arrival says nothing.
  parent_.resize(num_labels + 1);
  for (uint32_t l = 0; l <= num_labels; ++l) parent_[l] = l;
  const auto find = [&](uint32_t x) { return core::FindRoot(parent_.data(), x); };
  const auto min_contact = static_cast<uint32_t>(params_.rejoin_min_contact);
  const auto same_arrival = [&](uint32_t a, uint32_t b) {
    return lo_[a] > 0 && lo_[b] > 0 && lo_[b] - hi_[a] <= params_.gap_frames &&
           lo_[a] - hi_[b] <= params_.gap_frames;
  };
  for (uint32_t p = 1; p <= num_labels && params_.rejoin_min_contact > 0; ++p) {
    if (!part_[p]) continue;
    uint32_t best = 0, best_count = 0;
    for (const Contact& c : contacts_) {
      if (c.a != p && c.b != p) continue;
      const uint32_t t = c.a == p ? c.b : c.a;
      if (c.count < min_contact || !same_arrival(p, t)) continue;
      if (c.count > best_count || (c.count == best_count && t < best)) {
        best = t;
        best_count = c.count;
      }
    }
    if (best == 0) continue;
    const uint32_t rp = find(p), rt = find(best);
    if (rp == rt) continue;
    parent_[std::max(rp, rt)] = std::min(rp, rt);
    ++num_joined_;
  }
  // Pieces of one arrival (the segmentation cut one object put down into several): every pair
  // touching enough joins, whether split by arrival or not.
  if (join) {
    const auto min_join = static_cast<uint32_t>(params_.join_min_contact);
    for (const Contact& c : contacts_) {
      if ((c.wide < min_join && c.bridged < kBridgeMinContact) || !ArrivedTogether(c.a, c.b)) {
        continue;
      }
      const uint32_t ra = find(c.a), rb = find(c.b);
      if (ra == rb) continue;
      parent_[std::max(ra, rb)] = std::min(ra, rb);
      ++num_joined_;
    }
  }
  if (num_joined_ == 0) return;
  for (size_t i = 0; i < num_pixels_; ++i) {
    if (out[i] != 0 && out[i] <= num_labels) out[i] = find(out[i]);
  }
}

}  // namespace clutterseg::pipeline
