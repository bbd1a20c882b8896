#include "clutterseg/eval/metrics.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "clutterseg/core/assert.h"
#include "clutterseg/core/param_check.h"

namespace clutterseg::eval {
namespace {

// a / b > c / d for non-negative counts with b, d > 0, exactly (counts < 2^32, so the
// products fit in 64 bits).
bool RatioGreater(uint64_t a, uint64_t b, uint64_t c, uint64_t d) { return a * d > c * b; }

double SafeRatio(double num, double den) { return den > 0.0 ? num / den : 0.0; }

// Index of `label` in the sorted (label, value) list; the label must be present.
template <typename T>
size_t FindIndex(const std::vector<std::pair<uint32_t, T>>& sorted, uint32_t label) {
  const auto it = std::lower_bound(
      sorted.begin(), sorted.end(), label,
      [](const std::pair<uint32_t, T>& entry, uint32_t value) { return entry.first < value; });
  CLUTTERSEG_DEMAND(it != sorted.end() && it->first == label);
  return static_cast<size_t>(it - sorted.begin());
}

}  // namespace

GtConvention ParseGtConvention(std::string_view name) {
  if (name == "plain") return GtConvention::kPlain;
  if (name == "mosd-parts") return GtConvention::kMosdParts;
  if (name == "mosd-objects") return GtConvention::kMosdObjects;
  if (name == "ocid") return GtConvention::kOcid;
  throw std::invalid_argument("gt_convention: unknown value '" + std::string(name) +
                              "' (expected plain, mosd-parts, mosd-objects or ocid)");
}

std::string_view GtConventionName(GtConvention convention) {
  switch (convention) {
    case GtConvention::kPlain:
      return "plain";
    case GtConvention::kMosdParts:
      return "mosd-parts";
    case GtConvention::kMosdObjects:
      return "mosd-objects";
    case GtConvention::kOcid:
      return "ocid";
  }
  CLUTTERSEG_DEMAND(false);
  return "";
}

void EvalParams::ValidateOrThrow() const {
  core::ParamCheck("eval").InRange("min_coverage_percent", min_coverage_percent, 1, 100, "%");
  switch (gt_convention) {
    case GtConvention::kPlain:
    case GtConvention::kMosdParts:
    case GtConvention::kMosdObjects:
    case GtConvention::kOcid:
      return;
  }
  throw std::invalid_argument("gt_convention: invalid enum value " +
                              std::to_string(static_cast<int>(gt_convention)));
}

uint32_t MapGroundTruthLabel(uint32_t raw_label, const EvalParams& params) {
  switch (params.gt_convention) {
    case GtConvention::kPlain:
      return raw_label;
    case GtConvention::kMosdParts:
      return raw_label < 10 ? 0u : raw_label;
    case GtConvention::kMosdObjects:
      return raw_label < 10 ? 0u : raw_label / 10;
    case GtConvention::kOcid: {
      const auto& bg = params.ocid_background_labels;
      return std::find(bg.begin(), bg.end(), raw_label) != bg.end() ? 0u : raw_label;
    }
  }
  CLUTTERSEG_DEMAND(false);
  return 0;
}

namespace internal {

void CountTable::Clear() {
  if (size_ == 0) return;
  std::fill(counts_.begin(), counts_.end(), size_t{0});
  size_ = 0;
}

void CountTable::Add(uint64_t key, size_t count) {
  CLUTTERSEG_DEMAND(count > 0);
  if (2 * (size_ + 1) > counts_.size()) Grow();
  const size_t mask = counts_.size() - 1;
  // Fibonacci hashing; linear probing. A zero count marks an empty slot.
  size_t slot = static_cast<size_t>((key * 0x9E3779B97F4A7C15ull) >> 32) & mask;
  while (counts_[slot] != 0 && keys_[slot] != key) slot = (slot + 1) & mask;
  if (counts_[slot] == 0) {
    keys_[slot] = key;
    ++size_;
  }
  counts_[slot] += count;
}

void CountTable::AppendEntries(std::vector<std::pair<uint64_t, size_t>>* entries) const {
  for (size_t slot = 0; slot < counts_.size(); ++slot) {
    if (counts_[slot] != 0) entries->emplace_back(keys_[slot], counts_[slot]);
  }
}

void CountTable::Grow() {
  std::vector<uint64_t> old_keys = std::move(keys_);
  std::vector<size_t> old_counts = std::move(counts_);
  const size_t capacity = std::max<size_t>(64, 2 * old_counts.size());
  keys_.assign(capacity, 0);
  counts_.assign(capacity, 0);
  size_ = 0;
  for (size_t slot = 0; slot < old_counts.size(); ++slot) {
    if (old_counts[slot] != 0) Add(old_keys[slot], old_counts[slot]);
  }
}

}  // namespace internal

FrameEvaluator::FrameEvaluator(const EvalParams& params) : params_(params) {
  params_.ValidateOrThrow();
}

void FrameEvaluator::Evaluate(const core::PointCloud& gt, const core::PointCloud& pred,
                              FrameMetrics* metrics) {
  if (!gt.has_label()) throw std::runtime_error("ground truth cloud has no label field");
  if (!pred.has_label()) throw std::runtime_error("predicted cloud has no label field");
  if (gt.size() != pred.size() || gt.label.size() != gt.size() ||
      pred.label.size() != pred.size()) {
    throw std::runtime_error("point counts differ: ground truth has " + std::to_string(gt.size()) +
                             " points, prediction has " + std::to_string(pred.size()));
  }
  Evaluate(gt.xyz, gt.label, pred.label, metrics);
}

void FrameEvaluator::Evaluate(std::span<const core::Vec3f> xyz, std::span<const uint32_t> gt_labels,
                              std::span<const uint32_t> pred_labels, FrameMetrics* metrics) {
  CLUTTERSEG_DEMAND(metrics != nullptr);
  CLUTTERSEG_DEMAND(gt_labels.size() == xyz.size() && pred_labels.size() == xyz.size());
  FrameMetrics& m = *metrics;
  m.num_points = xyz.size();
  m.num_valid_points = 0;
  m.num_gt_objects = 0;
  m.num_segments = 0;
  m.scored = false;
  m.wov = m.tp = m.fp = m.fn = m.precision = m.recall = m.f1 = 0.0;
  m.over_segmented = m.under_segmented = 0;
  m.loss_merged = m.loss_split = m.loss_boundary = m.loss_background = 0.0;
  m.objects.clear();

  // 1. Sparse contingency table: consecutive equal (gt id, pred) keys are counted as one
  //    run (labels come in long runs along image rows), runs go into an open-addressing
  //    hash table, and only its distinct entries are sorted.
  table_.Clear();
  uint64_t run_key = 0;
  size_t run_count = 0;
  uint32_t last_raw = 0;
  uint32_t last_mapped = MapGroundTruthLabel(0, params_);
  for (size_t k = 0; k < xyz.size(); ++k) {
    if (!core::IsValid(xyz[k])) continue;
    ++m.num_valid_points;
    const uint32_t raw = gt_labels[k];
    if (raw != last_raw) {
      last_raw = raw;
      last_mapped = MapGroundTruthLabel(raw, params_);
    }
    const uint64_t key = (uint64_t{last_mapped} << 32) | pred_labels[k];
    if (run_count > 0 && key == run_key) {
      ++run_count;
    } else {
      if (run_count > 0) table_.Add(run_key, run_count);
      run_key = key;
      run_count = 1;
    }
  }
  if (run_count > 0) table_.Add(run_key, run_count);
  pairs_.clear();
  table_.AppendEntries(&pairs_);
  std::sort(pairs_.begin(), pairs_.end());
  const auto gt_of = [](uint64_t key) { return static_cast<uint32_t>(key >> 32); };
  const auto pred_of = [](uint64_t key) { return static_cast<uint32_t>(key & 0xffffffffu); };

  // 2. Segment sizes |s_j| over all valid points (background included), sorted by label.
  segment_sizes_.clear();
  for (const auto& [key, count] : pairs_) {
    if (pred_of(key) != 0) segment_sizes_.emplace_back(pred_of(key), count);
  }
  std::sort(segment_sizes_.begin(), segment_sizes_.end());
  size_t merged = 0;
  for (size_t i = 0; i < segment_sizes_.size(); ++i) {
    if (merged > 0 && segment_sizes_[merged - 1].first == segment_sizes_[i].first) {
      segment_sizes_[merged - 1].second += segment_sizes_[i].second;
    } else {
      segment_sizes_[merged++] = segment_sizes_[i];
    }
  }
  segment_sizes_.resize(merged);
  m.num_segments = static_cast<int>(segment_sizes_.size());

  // 3. Per ground-truth object: size, best segment, coverage. pairs_ is sorted by gt id
  //    first, so each object is one contiguous group, and within it labels increase.
  segment_cover_counts_.clear();
  for (const auto& entry : segment_sizes_) segment_cover_counts_.emplace_back(entry.first, 0);
  const uint64_t percent = static_cast<uint64_t>(params_.min_coverage_percent);
  const auto covers = [percent](uint64_t intersection, uint64_t gt_size) {
    return 100 * intersection >= percent * gt_size;
  };
  size_t begin = 0;
  while (begin < pairs_.size()) {
    const uint32_t gt_id = gt_of(pairs_[begin].first);
    size_t end = begin;
    size_t size = 0;
    while (end < pairs_.size() && gt_of(pairs_[end].first) == gt_id) size += pairs_[end++].second;
    if (gt_id != 0) {
      ObjectScore obj;
      obj.gt_id = gt_id;
      obj.size = size;
      uint64_t best_union = 1;
      for (size_t i = begin; i < end; ++i) {
        const uint32_t label = pred_of(pairs_[i].first);
        if (label == 0) continue;
        const uint64_t inter = pairs_[i].second;
        const uint64_t seg_size = segment_sizes_[FindIndex(segment_sizes_, label)].second;
        const uint64_t uni = size + seg_size - inter;
        // Larger IoU wins; equal IoU: larger intersection; then the smaller label, which
        // is the one already held since labels increase within the group.
        const bool better =
            obj.best_segment == 0 || RatioGreater(inter, uni, obj.intersection, best_union) ||
            (!RatioGreater(obj.intersection, best_union, inter, uni) && inter > obj.intersection);
        if (better) {
          obj.best_segment = label;
          obj.best_segment_size = seg_size;
          obj.intersection = inter;
          best_union = uni;
        }
        if (covers(inter, size)) {
          ++obj.covering_segments;
          ++segment_cover_counts_[FindIndex(segment_cover_counts_, label)].second;
        }
      }
      if (obj.best_segment != 0) {
        obj.overlap = static_cast<double>(obj.intersection) / static_cast<double>(best_union);
        obj.tp = static_cast<double>(obj.intersection) / static_cast<double>(size);
        obj.fp = static_cast<double>(obj.best_segment_size - obj.intersection) /
                 static_cast<double>(obj.best_segment_size);
        obj.fn = static_cast<double>(size - obj.intersection) / static_cast<double>(size);
      } else {
        obj.fn = 1.0;
      }
      obj.over_segmented = obj.covering_segments >= 2;
      m.objects.push_back(obj);
    }
    begin = end;
  }

  // 4. Under-segmentation and where the overlap is lost (FrameMetrics) need every segment's
  //    cover count, so they are a second pass. The points of an object's best segment on
  //    other objects come from the table sorted by segment.
  pairs_by_segment_.clear();
  for (const auto& [key, count] : pairs_) {
    pairs_by_segment_.emplace_back((uint64_t{pred_of(key)} << 32) | gt_of(key), count);
  }
  std::sort(pairs_by_segment_.begin(), pairs_by_segment_.end());
  const auto object_size = [&m](uint32_t gt_id) {
    const auto it =
        std::lower_bound(m.objects.begin(), m.objects.end(), gt_id,
                         [](const ObjectScore& obj, uint32_t value) { return obj.gt_id < value; });
    CLUTTERSEG_DEMAND(it != m.objects.end() && it->gt_id == gt_id);
    return static_cast<uint64_t>(it->size);
  };
  // A segment's points on the background: its entry (label, 0) comes first in its range.
  const auto background_points = [this](uint32_t label) -> uint64_t {
    const uint64_t key = uint64_t{label} << 32;
    const auto it = std::lower_bound(pairs_by_segment_.begin(), pairs_by_segment_.end(),
                                     std::make_pair(key, size_t{0}));
    return it != pairs_by_segment_.end() && it->first == key ? it->second : 0;
  };
  enum Cause { kMerged, kSplit, kBoundary, kBackground };
  double lost[4] = {0.0, 0.0, 0.0, 0.0};
  begin = 0;
  size_t obj_index = 0;
  while (begin < pairs_.size()) {
    const uint32_t gt_id = gt_of(pairs_[begin].first);
    size_t end = begin;
    while (end < pairs_.size() && gt_of(pairs_[end].first) == gt_id) ++end;
    if (gt_id != 0) {
      ObjectScore& obj = m.objects[obj_index++];
      size_t counts[4] = {0, 0, 0, 0};
      // Points of g_i outside s_i, by the segment holding them.
      for (size_t i = begin; i < end; ++i) {
        const uint32_t label = pred_of(pairs_[i].first);
        const size_t count = pairs_[i].second;
        if (label == 0) {
          counts[kBackground] += count;
          continue;
        }
        const bool covers_own = covers(count, obj.size);
        const int covered = segment_cover_counts_[FindIndex(segment_cover_counts_, label)].second;
        if (covers_own && covered >= 2) obj.under_segmented = true;
        if (label == obj.best_segment) continue;
        if (covered - (covers_own ? 1 : 0) >= 1) {  // covers another object
          counts[covers_own ? kMerged : kBoundary] += count;
        } else {
          const bool mostly_background = 2 * background_points(label) >
                                         segment_sizes_[FindIndex(segment_sizes_, label)].second;
          counts[mostly_background ? kBackground : kSplit] += count;
        }
      }
      // Points of s_i outside g_i, by the object they belong to.
      if (obj.best_segment != 0) {
        const uint64_t first = uint64_t{obj.best_segment} << 32;
        for (auto it = std::lower_bound(pairs_by_segment_.begin(), pairs_by_segment_.end(),
                                        std::make_pair(first, size_t{0}));
             it != pairs_by_segment_.end() && (it->first >> 32) == obj.best_segment; ++it) {
          const auto other = static_cast<uint32_t>(it->first & 0xffffffffu);
          if (other == gt_id) continue;
          if (other == 0) {
            counts[kBackground] += it->second;
          } else {
            counts[covers(it->second, object_size(other)) ? kMerged : kBoundary] += it->second;
          }
        }
      }
      // Each error point weighs |g_i| / |g_i ∪ s_i|, so they add up to |g_i| (1 - Ov_i).
      const double weight =
          static_cast<double>(obj.size) /
          static_cast<double>(obj.size + obj.best_segment_size - obj.intersection);
      for (int c = 0; c < 4; ++c) lost[c] += weight * static_cast<double>(counts[c]);
    }
    begin = end;
  }

  // 5. Frame figures.
  m.num_gt_objects = static_cast<int>(m.objects.size());
  if (m.objects.empty()) return;
  m.scored = true;
  double weighted_overlap = 0.0;
  double total_size = 0.0;
  for (const ObjectScore& obj : m.objects) {
    weighted_overlap += static_cast<double>(obj.size) * obj.overlap;
    total_size += static_cast<double>(obj.size);
    m.tp += obj.tp;
    m.fp += obj.fp;
    m.fn += obj.fn;
    m.over_segmented += obj.over_segmented ? 1 : 0;
    m.under_segmented += obj.under_segmented ? 1 : 0;
  }
  const double n = static_cast<double>(m.objects.size());
  m.wov = weighted_overlap / total_size;
  m.tp /= n;
  m.fp /= n;
  m.fn /= n;
  m.precision = SafeRatio(m.tp, m.tp + m.fp);
  m.recall = SafeRatio(m.tp, m.tp + m.fn);
  m.f1 = SafeRatio(2.0 * m.precision * m.recall, m.precision + m.recall);
  m.loss_merged = lost[kMerged] / total_size;
  m.loss_split = lost[kSplit] / total_size;
  m.loss_boundary = lost[kBoundary] / total_size;
  m.loss_background = lost[kBackground] / total_size;
}

Summary Summarize(std::span<const FrameMetrics> frames) {
  Summary s;
  s.frames = static_cast<int>(frames.size());
  for (const FrameMetrics& f : frames) {
    s.gt_objects += f.num_gt_objects;
    s.segments += f.num_segments;
    s.over_segmented += f.over_segmented;
    s.under_segmented += f.under_segmented;
    if (!f.scored) continue;
    ++s.frames_scored;
    s.wov += f.wov;
    s.tp += f.tp;
    s.fp += f.fp;
    s.fn += f.fn;
    s.precision += f.precision;
    s.recall += f.recall;
    s.f1 += f.f1;
    s.loss_merged += f.loss_merged;
    s.loss_split += f.loss_split;
    s.loss_boundary += f.loss_boundary;
    s.loss_background += f.loss_background;
  }
  if (s.frames_scored > 0) {
    const double n = s.frames_scored;
    s.wov /= n;
    s.tp /= n;
    s.fp /= n;
    s.fn /= n;
    s.precision /= n;
    s.recall /= n;
    s.f1 /= n;
    s.loss_merged /= n;
    s.loss_split /= n;
    s.loss_boundary /= n;
    s.loss_background /= n;
  }
  if (s.frames > 0) {
    const double n = s.frames;
    s.mean_gt_objects = static_cast<double>(s.gt_objects) / n;
    s.mean_segments = static_cast<double>(s.segments) / n;
    s.mean_over_segmented = static_cast<double>(s.over_segmented) / n;
    s.mean_under_segmented = static_cast<double>(s.under_segmented) / n;
  }
  return s;
}

}  // namespace clutterseg::eval
