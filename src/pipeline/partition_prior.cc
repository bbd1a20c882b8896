#include "clutterseg/pipeline/partition_prior.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "clutterseg/core/assert.h"
#include "clutterseg/core/label_scan.h"
#include "clutterseg/core/param_check.h"
#include "clutterseg/core/union_find.h"

namespace clutterseg::pipeline {
namespace {

template <typename T>
T* FindCount(std::vector<T>* v, uint32_t a, uint32_t b) {
  for (T& c : *v) {
    if constexpr (requires { c.b; }) {
      if (c.a == a && c.b == b) return &c;
    } else {
      if (c.id == a) return &c;
    }
  }
  return nullptr;
}

// Bits of a pixel's stillness (StepStillness).
constexpr uint8_t kValid = 1;        // a depth in this frame
constexpr uint8_t kStill = 2;        // within the band of the previous frame's depth
constexpr uint8_t kEstablished = 4;  // still for hold_frames frames in a row

// Each pixel's stillness against the previous frame's depth `prev_z` (NaN where there was
// none) into `state`, and its still age (frames in a row, up to 255) updated. Written without
// branches and with restrict pointers, so that the compiler vectorises it; the band by value.
void StepStillness(size_t num, const core::Vec3f* __restrict xyz, const float* __restrict prev_z,
                   const TemporalFilterParams band, int hold, uint8_t* __restrict age,
                   uint8_t* __restrict state) {
  for (size_t i = 0; i < num; ++i) {
    const float z = xyz[i].z;
    const int32_t valid = z > 0.f;
    const int32_t still = valid & (std::abs(z - prev_z[i]) <= band.BandAt(z));  // NaN: false
    const int32_t a = age[i];
    const int32_t next = still * (a + (a < 255));
    age[i] = static_cast<uint8_t>(next);
    state[i] =
        static_cast<uint8_t>(valid * kValid + still * kStill + (next >= hold) * kEstablished);
  }
}

}  // namespace

void PartitionPriorParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("hold_frames", hold_frames, 1, 1000, "(1 = off)");
  check.Require(min_still_share > 0.f && min_still_share <= 1.f, "min_still_share", min_still_share,
                "a share in (0, 1]");
  check.Require(min_cover_share >= 0.5f && min_cover_share < 1.f, "min_cover_share",
                min_cover_share, "a share in [0.5, 1)");
  check.InRange("min_pixels", min_pixels, 1, 1 << 24);
  check.InRange("arrival_gap_frames", arrival_gap_frames, 0, 100000, "(0 = off)");
  check.InRange("arrival_confirm_frames", arrival_confirm_frames, 1, 255);
  check.Require(arrival_min_share > 0.f && arrival_min_share <= 1.f, "arrival_min_share",
                arrival_min_share, "a share in (0, 1]");
  check.InRange("arrival_moved_min_pixels", arrival_moved_min_pixels, 1, 1 << 24);
  check.InRange("arrival_rejoin_min_contact", arrival_rejoin_min_contact, 0, 1 << 24,
                "(0 = never)");
  check.InRange("arrival_join_min_contact", arrival_join_min_contact, 0, 1 << 24, "(0 = never)");
}

PartitionPrior::PartitionPrior(const PartitionPriorParams& params, const TemporalFilterParams& band,
                               core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)),
      band_(band),
      pool_(pool),
      extractor_(pool),
      history_(params, band, pool) {}

PartitionPrior::~PartitionPrior() = default;

void PartitionPrior::Reset() {
  have_prev_ = false;
  pending_result_ = nullptr;
  pending_cloud_ = {};
  history_.Reset();
  merges_.clear();
  splits_.clear();
}

size_t PartitionPrior::memory_bytes() const {
  return prev_labels_.capacity() * sizeof(uint32_t) + prev_z_.capacity() * sizeof(float) +
         still_age_.capacity() + history_.memory_bytes();
}

bool PartitionPrior::Apply(const core::PointCloudView& cloud, int64_t frame_seq,
                           SegmentationResult* result, std::span<const float> scene_z) {
  const bool changed = Relabel(cloud, frame_seq, result, scene_z);
  RememberPending(pool_);
  return changed;
}

void PartitionPrior::Remember() { RememberPending(nullptr); }

void PartitionPrior::RememberPending(core::ThreadPool* pool) {
  if (pending_result_ == nullptr) return;
  RememberOutput(pending_cloud_, *pending_result_, counts_rp_, pending_have_counts_, pool);
  pending_result_ = nullptr;
  pending_cloud_ = {};
}

void PartitionPrior::Defer(const core::PointCloudView& cloud, const SegmentationResult* result,
                           bool have_counts) {
  pending_result_ = result;
  pending_cloud_ = cloud;
  pending_have_counts_ = have_counts;
}

bool PartitionPrior::Relabel(const core::PointCloudView& cloud, int64_t frame_seq,
                             SegmentationResult* result, std::span<const float> scene_z) {
  CLUTTERSEG_DEMAND(pending_result_ == nullptr);  // Remember of the last frame ran
  counts_ = PartitionPriorCounts{};
  if (!enabled()) return false;
  const int w = result->labels.width, h = result->labels.height;
  const size_t num_pixels = result->labels.data.size();
  if (!cloud.organized() || cloud.size() != num_pixels || w != cloud.width || h != cloud.height) {
    Reset();
    return false;
  }
  if (have_prev_ && (frame_seq <= prev_seq_ || w != width_ || h != height_)) Reset();
  uint32_t* out = result->labels.data.data();
  const uint32_t* labels = out;
  // Surfaces of different arrival first: the hysteresis below then holds what they change too.
  uint32_t n = static_cast<uint32_t>(result->objects.size());
  const uint32_t with_arrivals = history_.Apply(cloud, scene_z, frame_seq, n, out);
  counts_.arrival_splits = history_.num_split();
  counts_.arrival_moves = history_.num_moved();
  counts_.arrival_joins = history_.num_joined();
  const bool arrivals = history_.changed();
  if (arrivals) n = Compact(with_arrivals + 1, out, num_pixels, out);
  if (!have_prev_) {
    if (arrivals) Describe(cloud, n, result);
    counts_rp_.clear();
    Defer(cloud, result, false);
    prev_seq_ = frame_seq;
    return arrivals;
  }
  const uint32_t m = static_cast<uint32_t>(prev_id_.size() - 1);
  const size_t stride = m + 1;

  // Still pixels per (segment, previous object), and the valid pixels of each segment.
  // Each pixel's still age (frames in a row within the band) is updated on the way; a
  // previous object is established when most of its still pixels have been still for
  // hold_frames frames, so that a partition made in the frame of a change (the first view
  // after an occluder passed) is not held.
  // Pixels that are background now and were before (the pair 0, 0) are not counted: no rule
  // reads that pair, and most of the image is such pixels (core::ForEachLabelled).
  counts_rp_.assign((n + 1) * stride, 0u);
  valid_r_.assign(n + 1, 0u);
  established_p_.assign(m + 1, 0u);
  state_.resize(num_pixels);
  {
    // Per chunk of pixels (on the pool): the stillness, then into one table: counts_rp_,
    // valid_r_, established_p_.
    const uint8_t* state = state_.data();
    const uint32_t* prev = prev_labels_.data();
    const size_t num_counts = counts_rp_.size();
    tables_.assign(num_counts + valid_r_.size() + established_p_.size(), 0u);
    core::CountInChunks(pool_, num_pixels, core::kPixelGrain, tables_.size(), &chunk_tables_,
                        tables_.data(), [&](size_t b, size_t e, uint32_t* table) {
                          uint32_t* counts = table;
                          uint32_t* valid = table + num_counts;
                          uint32_t* established = valid + (n + 1);
                          StepStillness(e - b, cloud.xyz.data() + b, prev_z_.data() + b, band_,
                                        params_.hold_frames, still_age_.data() + b,
                                        state_.data() + b);
                          core::ForEachLabelled(labels + b, prev + b, e - b, [&](size_t j) {
                            const size_t i = b + j;
                            const uint32_t s = state[i];
                            if ((labels[i] | prev[i]) == 0 || !(s & kValid)) return;
                            const uint32_t r = labels[i] <= n ? labels[i] : 0;
                            ++valid[r];
                            if (!(s & kStill)) return;
                            const uint32_t p = prev[i];
                            ++counts[r * stride + p];
                            established[p] += (s & kEstablished) >> 2;
                          });
                        });
    const auto from = tables_.begin();
    const auto valid_at = from + static_cast<ptrdiff_t>(num_counts);
    const auto established_at = valid_at + static_cast<ptrdiff_t>(n + 1);
    std::copy(from, valid_at, counts_rp_.begin());
    std::copy(valid_at, established_at, valid_r_.begin());
    std::copy(established_at, tables_.end(), established_p_.begin());
  }
  still_r_.assign(n + 1, 0u);
  still_p_.assign(m + 1, 0u);
  for (uint32_t r = 0; r <= n; ++r) {
    for (uint32_t p = 0; p <= m; ++p) {
      const uint32_t c = counts_rp_[r * stride + p];
      still_r_[r] += c;
      still_p_[p] += c;
    }
  }
  const auto still = [&](uint32_t r) {
    return r >= 1 && valid_r_[r] > 0 &&
           static_cast<float>(still_r_[r]) >= params_.min_still_share * valid_r_[r];
  };
  const auto min_px = static_cast<uint32_t>(params_.min_pixels);
  const auto established = [&](uint32_t p) {
    return static_cast<float>(established_p_[p]) >= params_.min_still_share * still_p_[p];
  };

  // Merges: a still segment covering several previous objects.
  new_merges_.clear();
  new_splits_.clear();
  covered_n_.assign(n + 1, 0);
  map_.resize(n + 1);
  for (uint32_t r = 0; r <= n; ++r) map_[r] = r;
  if (split_.size() < n + 1) split_.resize(n + 1);
  for (auto& s : split_) s.clear();
  uint32_t next_label = n + 1;
  std::vector<uint32_t>& covered = covered_;
  std::vector<int>& parent = parent_;
  const bool holding = params_.hold_frames > 1;
  for (uint32_t r = 1; holding && r <= n; ++r) {
    covered.clear();
    for (uint32_t p = 1; p <= m; ++p) {
      if (still_p_[p] >= min_px &&
          static_cast<float>(counts_rp_[r * stride + p]) >= params_.min_cover_share * still_p_[p]) {
        covered.push_back(p);
      }
    }
    covered_n_[r] = static_cast<int>(covered.size());
    if (covered.size() < 2 || !still(r) ||
        !std::all_of(covered.begin(), covered.end(), established)) {
      continue;
    }
    // Join the previous objects whose pair has been merged for hold_frames frames in a row.
    parent.resize(covered.size());
    for (size_t k = 0; k < covered.size(); ++k) parent[k] = static_cast<int>(k);
    for (size_t i = 0; i < covered.size(); ++i) {
      for (size_t j = i + 1; j < covered.size(); ++j) {
        uint32_t a = prev_id_[covered[i]], b = prev_id_[covered[j]];
        if (a > b) std::swap(a, b);
        const PairCount* before = FindCount(&merges_, a, b);
        const int count = (before != nullptr ? before->count : 0) + 1;
        new_merges_.push_back(PairCount{a, b, count});
        if (count >= params_.hold_frames) {
          parent[static_cast<size_t>(core::FindRoot(parent.data(), static_cast<int>(i)))] =
              core::FindRoot(parent.data(), static_cast<int>(j));
        }
      }
    }
    // One output object per group of joined previous objects; the group holding the most
    // still pixels of the segment keeps its label.
    std::vector<uint32_t>& group_px = group_px_;
    group_px.assign(covered.size(), 0u);
    for (size_t k = 0; k < covered.size(); ++k) {
      group_px[static_cast<size_t>(core::FindRoot(parent.data(), static_cast<int>(k)))] +=
          counts_rp_[r * stride + covered[k]];
    }
    int keeper = -1, groups = 0;
    for (size_t k = 0; k < covered.size(); ++k) {
      if (core::FindRoot(parent.data(), static_cast<int>(k)) != static_cast<int>(k)) continue;
      ++groups;
      if (keeper < 0 || group_px[k] > group_px[static_cast<size_t>(keeper)]) {
        keeper = static_cast<int>(k);
      }
    }
    if (groups < 2) {
      ++counts_.passed_merges;
      continue;
    }
    ++counts_.held_merges;
    std::vector<uint32_t>& to = split_[r];
    to.assign(m + 1, 0u);
    std::vector<uint32_t>& group_label = group_label_;
    group_label.assign(covered.size(), 0u);
    for (size_t k = 0; k < covered.size(); ++k) {
      if (core::FindRoot(parent.data(), static_cast<int>(k)) != static_cast<int>(k)) continue;
      group_label[k] = static_cast<int>(k) == keeper ? r : next_label++;
    }
    for (size_t k = 0; k < covered.size(); ++k) {
      to[covered[k]] =
          group_label[static_cast<size_t>(core::FindRoot(parent.data(), static_cast<int>(k)))];
    }
  }

  // A held merge cuts back to each previous object its pixels; those of an object whose rest
  // is a segment of its own now (lying within it, covering nothing else: the object was cut in
  // two and one part merged with a neighbour) join that segment, so the object stays whole.
  for (uint32_t r = 1; params_.cut_piece_joins_rest && r <= n; ++r) {
    std::vector<uint32_t>& to = split_[r];
    for (uint32_t p = 1; p <= m && !to.empty(); ++p) {
      if (to[p] <= n) continue;  // not covered, or the keeper's group
      uint32_t rest = 0;
      for (uint32_t q = 1; q <= n; ++q) {
        const uint32_t c = counts_rp_[q * stride + p];
        if (q == r || c == 0 || !split_[q].empty() || covered_n_[q] > 1 || !still(q)) continue;
        if (static_cast<float>(c) < params_.min_cover_share * still_r_[q]) continue;
        if (rest == 0 || c > counts_rp_[rest * stride + p]) rest = q;
      }
      if (rest == 0) continue;
      const uint32_t piece = to[p];
      for (uint32_t k = 1; k <= m; ++k) {
        if (to[k] == piece) to[k] = rest;
      }
    }
  }

  // Splits: still segments lying within one previous object, each covering nothing else.
  for (uint32_t p = 1; holding && p <= m; ++p) {
    if (still_p_[p] < min_px || !established(p)) continue;
    uint32_t keeper = 0, parts = 0;
    bool all_still = true;
    for (uint32_t r = 1; r <= n; ++r) {
      const uint32_t c = counts_rp_[r * stride + p];
      if (c == 0 || static_cast<float>(c) < params_.min_cover_share * still_r_[r]) continue;
      if (!split_[r].empty() || covered_n_[r] > 1) continue;
      ++parts;
      all_still = all_still && still(r);
      if (keeper == 0 || c > counts_rp_[keeper * stride + p]) keeper = r;
    }
    if (parts < 2 || !all_still) continue;
    const IdCount* before = FindCount(&splits_, prev_id_[p], 0);
    const int count = (before != nullptr ? before->count : 0) + 1;
    new_splits_.push_back(IdCount{prev_id_[p], count});
    if (count >= params_.hold_frames) {
      ++counts_.passed_splits;
      continue;
    }
    ++counts_.held_splits;
    for (uint32_t r = 1; r <= n; ++r) {
      const uint32_t c = counts_rp_[r * stride + p];
      if (c == 0 || static_cast<float>(c) < params_.min_cover_share * still_r_[r]) continue;
      if (!split_[r].empty() || covered_n_[r] > 1) continue;
      map_[r] = keeper;
    }
  }
  merges_.swap(new_merges_);
  splits_.swap(new_splits_);

  const bool held = counts_.held_merges > 0 || counts_.held_splits > 0;
  uint32_t num_labels = n;
  if (held) {
    // Output labels: joined parts to their keeper; pixels of a cut segment to the part of
    // their previous object, or, having none, to the nearest part within the segment.
    out_labels_.resize(num_pixels);
    pending_.clear();
    for (size_t i = 0; i < num_pixels; ++i) {
      const uint32_t r = labels[i] <= n ? labels[i] : 0;
      if (r != 0 && !split_[r].empty()) {
        const uint32_t to = split_[r][prev_labels_[i]];
        out_labels_[i] = to;
        if (to == 0) pending_.push_back(static_cast<uint32_t>(i));
      } else {
        out_labels_[i] = map_[r];
      }
    }
    FillFromNeighbours(labels, w, h, &pending_, &pending_next_, &taken_, out_labels_.data());
    num_labels = Compact(next_label, out_labels_.data(), num_pixels, out);
  }
  if (!held && !arrivals) {
    Defer(cloud, result, true);
    prev_seq_ = frame_seq;
    return false;
  }
  Describe(cloud, num_labels, result);

  // The output against the previous frame, for the ids the next frame's counts refer to.
  counts_rp_.assign((num_labels + 1) * stride, 0u);
  for (size_t i = 0; i < num_pixels; ++i) {
    if (state_[i] & kStill) ++counts_rp_[out[i] * stride + prev_labels_[i]];
  }
  Defer(cloud, result, true);
  prev_seq_ = frame_seq;
  return true;
}

void PartitionPrior::Describe(const core::PointCloudView& cloud, uint32_t num_labels,
                              SegmentationResult* result) {
  result->objects.assign(num_labels, Object{});
  for (uint32_t k = 0; k < num_labels; ++k) result->objects[k].id = k + 1;
  // The stage time stays the segmenter's; the recomputation is this step's time.
  const double segmenter_objects_ms = result->times[Stage::kObjects];
  extractor_.Compute(cloud, result);
  result->times[Stage::kObjects] = segmenter_objects_ms;
}

uint32_t PartitionPrior::Compact(uint32_t num_in, const uint32_t* in, size_t num_pixels,
                                 uint32_t* out) {
  // Labels in order of first use by label value: the segments, then the parts cut off.
  std::vector<uint32_t>& final_label = final_label_;
  std::vector<uint8_t>& used = used_;
  final_label.assign(num_in, 0u);
  used.assign(num_in, 0u);
  for (size_t i = 0; i < num_pixels; ++i) used[in[i]] = 1;
  uint32_t count = 0;
  for (uint32_t l = 1; l < num_in; ++l) {
    if (used[l]) final_label[l] = ++count;
  }
  for (size_t i = 0; i < num_pixels; ++i) out[i] = final_label[in[i]];
  return count;
}

void PartitionPrior::RememberOutput(const core::PointCloudView& cloud,
                                    const SegmentationResult& result,
                                    const std::vector<uint32_t>& counts, bool have_counts,
                                    core::ThreadPool* pool) {
  const size_t num_pixels = result.labels.data.size();
  const uint32_t n = static_cast<uint32_t>(result.objects.size());
  // Ids: an object takes the id of the previous object holding most of its still pixels
  // (at least half of them), and the previous object's largest share decides between two
  // claimants; the rest get new ids.
  std::vector<uint32_t>& id = id_work_;
  id.assign(n + 1, 0u);
  if (have_counts && have_prev_) {
    const uint32_t m = static_cast<uint32_t>(prev_id_.size() - 1);
    const size_t stride = m + 1;
    owner_.assign(m + 1, 0u);
    owner_count_.assign(m + 1, 0u);
    for (uint32_t o = 1; o <= n; ++o) {
      uint32_t total = 0, best_p = 0, best_c = 0;
      for (uint32_t p = 0; p <= m; ++p) {
        const uint32_t c = counts[o * stride + p];
        total += c;
        if (p >= 1 && c > best_c) {
          best_c = c;
          best_p = p;
        }
      }
      if (best_p == 0 || 2 * best_c < total) continue;
      if (owner_[best_p] == 0 || best_c > owner_count_[best_p]) {
        owner_[best_p] = o;
        owner_count_[best_p] = best_c;
      }
    }
    for (uint32_t p = 1; p <= m; ++p) {
      if (owner_[p] != 0) id[owner_[p]] = prev_id_[p];
    }
  }
  for (uint32_t o = 1; o <= n; ++o) {
    if (id[o] == 0) id[o] = next_id_++;
  }
  prev_id_.swap(id);
  prev_labels_.resize(num_pixels);
  if (still_age_.size() != num_pixels || !have_prev_) still_age_.assign(num_pixels, 0);
  prev_z_.resize(num_pixels);
  core::ForChunks(pool, num_pixels, core::kPixelGrain, [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) {
      const uint32_t l = result.labels.data[i];
      prev_labels_[i] = l <= n ? l : 0;
      const float z = cloud.xyz[i].z;
      prev_z_[i] = z > 0.f ? z : std::numeric_limits<float>::quiet_NaN();
    }
  });
  width_ = result.labels.width;
  height_ = result.labels.height;
  have_prev_ = true;
}

}  // namespace clutterseg::pipeline
