#include "clutterseg/daemon/latency_stats.h"

#include <algorithm>
#include <cmath>

#include "clutterseg/core/assert.h"

namespace clutterseg::daemon {

LatencyWindow::LatencyWindow(size_t capacity) : samples_(capacity), scratch_(capacity) {
  CLUTTERSEG_DEMAND(capacity > 0);
}

void LatencyWindow::Add(double ms) {
  samples_[next_] = ms;
  next_ = (next_ + 1) % samples_.size();
  count_ = std::min(count_ + 1, samples_.size());
}

LatencySummary LatencyWindow::TakeSummary() {
  LatencySummary s;
  s.count = count_;
  if (count_ == 0) return s;
  // The newest count_ samples end just before next_.
  for (size_t i = 0; i < count_; ++i) {
    scratch_[i] = samples_[(next_ + samples_.size() - count_ + i) % samples_.size()];
  }
  auto begin = scratch_.begin();
  auto end = begin + static_cast<std::ptrdiff_t>(count_);
  auto rank = [&](double q) {
    const size_t k = static_cast<size_t>(std::ceil(q * static_cast<double>(count_))) - 1;
    std::nth_element(begin, begin + static_cast<std::ptrdiff_t>(k), end);
    return scratch_[k];
  };
  s.p50_ms = rank(0.50);
  s.p99_ms = rank(0.99);
  s.max_ms = *std::max_element(begin, end);
  count_ = 0;
  next_ = 0;
  return s;
}

}  // namespace clutterseg::daemon
