#pragma once

#include <cstddef>
#include <vector>

namespace clutterseg::daemon {

/// Percentiles of the latencies recorded since the last summary.
struct LatencySummary {
  double p50_ms{0.0};
  double p99_ms{0.0};
  double max_ms{0.0};
  size_t count{0};
};

/// Collects latency samples over one status period. Keeps at most `capacity` samples (the
/// newest); storage is allocated once. Thread-safety: none (one owner thread).
class LatencyWindow {
 public:
  explicit LatencyWindow(size_t capacity = 4096);
  void Add(double ms);
  /// Nearest-rank p50 / p99 of the samples since the last call, then forgets them. All zero
  /// when there was no sample.
  LatencySummary TakeSummary();

 private:
  std::vector<double> samples_;
  std::vector<double> scratch_;
  size_t next_{0};
  size_t count_{0};
};

}  // namespace clutterseg::daemon
