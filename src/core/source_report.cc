#include "clutterseg/core/source_report.h"

#include <utility>

namespace clutterseg::core {

const char* ToString(SkipReason reason) {
  switch (reason) {
    case SkipReason::kUnreadable:
      return "unreadable";
    case SkipReason::kTooLarge:
      return "too_large";
    case SkipReason::kSizeMismatch:
      return "size_mismatch";
    case SkipReason::kNotDelivered:
      return "not_delivered";
  }
  return "unreadable";
}

uint64_t SourceReport::frames_skipped() const {
  uint64_t n = 0;
  for (uint64_t c : skipped) n += c;
  return n;
}

std::string SourceReport::ToString() const {
  std::string s = std::to_string(frames_delivered);
  if (frames_in_source >= 0) {
    s += " of " + std::to_string(frames_in_source);
    if (passes_completed > 1) s += " x " + std::to_string(passes_completed) + " passes";
  }
  s += " frames delivered, " + std::to_string(frames_skipped()) + " skipped";
  std::string reasons;
  for (size_t i = 0; i < kNumSkipReasons; ++i) {
    if (skipped[i] == 0) continue;
    if (!reasons.empty()) reasons += ", ";
    reasons += std::to_string(skipped[i]) + " " + core::ToString(static_cast<SkipReason>(i));
  }
  if (!reasons.empty()) s += " (" + reasons + ")";
  s += ", " + std::to_string(frames_empty) + " empty";
  if (frames_without_color > 0)
    s += ", " + std::to_string(frames_without_color) + " without colour";
  if (color_frames_unmatched > 0) {
    s += ", " + std::to_string(color_frames_unmatched) + " colour frames unmatched";
  }
  if (!recent_skips.empty()) s += "; last skipped: " + recent_skips.back().what;
  return s;
}

void SourceCounters::SetFramesInSource(int64_t frames) {
  std::lock_guard<std::mutex> lock(mutex_);
  report_.frames_in_source = frames;
}

void SourceCounters::Delivered(bool empty, bool without_color) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++report_.frames_delivered;
  report_.frames_empty += empty ? 1 : 0;
  report_.frames_without_color += without_color ? 1 : 0;
}

void SourceCounters::Skipped(SkipReason reason, std::string what, uint64_t count) {
  if (count == 0) return;
  std::lock_guard<std::mutex> lock(mutex_);
  report_.skipped[static_cast<size_t>(reason)] += count;
  serial_ += count;
  std::vector<SkippedFrame>& recent = report_.recent_skips;
  if (recent.size() >= SourceReport::kMaxRecentSkips) recent.erase(recent.begin());
  recent.push_back(SkippedFrame{serial_, count, reason, std::move(what)});
}

void SourceCounters::ColorUnmatched(uint64_t count) {
  std::lock_guard<std::mutex> lock(mutex_);
  report_.color_frames_unmatched += count;
}

void SourceCounters::PassCompleted() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++report_.passes_completed;
}

SourceReport SourceCounters::Snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return report_;
}

}  // namespace clutterseg::core
