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

LatencyHistogram::LatencyHistogram() : bins_(kBins + 1, 0) {}

void LatencyHistogram::Add(double ms) {
  if (!(ms >= 0.0)) ms = 0.0;
  const double bin = std::floor(ms / kBinMs);
  bins_[bin < static_cast<double>(kBins) ? static_cast<size_t>(bin) : kBins] += 1;
  ++count_;
  sum_ms_ += ms;
  max_ms_ = std::max(max_ms_, ms);
}

double LatencyHistogram::Percentile(double q) const {
  if (count_ == 0) return 0.0;
  const auto rank = static_cast<uint64_t>(std::ceil(q * static_cast<double>(count_)));
  uint64_t seen = 0;
  for (size_t b = 0; b < kBins; ++b) {
    seen += bins_[b];
    if (seen >= rank && bins_[b] > 0) {
      return std::min(max_ms_, static_cast<double>(b + 1) * kBinMs);
    }
  }
  return max_ms_;
}

}  // namespace clutterseg::daemon
