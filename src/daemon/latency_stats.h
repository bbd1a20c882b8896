#pragma once

#include <cstddef>
#include <cstdint>
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

/// Latencies over a whole run, for the end-of-run summary: a fixed histogram of 0.05 ms bins
/// up to 2 s (and one overflow bin), so a run of days costs the same 320 kB as a run of
/// seconds. Percentiles are the upper edge of the bin holding the nearest-rank sample
/// (at most 0.05 ms above it; above 2 s, the largest sample). Thread-safety: none.
class LatencyHistogram {
 public:
  LatencyHistogram();
  void Add(double ms);
  uint64_t count() const { return count_; }
  /// Nearest-rank percentile `q` in (0, 1], milliseconds; 0 without samples.
  double Percentile(double q) const;
  double max_ms() const { return max_ms_; }
  double mean_ms() const { return count_ > 0 ? sum_ms_ / static_cast<double>(count_) : 0.0; }

 private:
  static constexpr double kBinMs = 0.05;
  static constexpr size_t kBins = 40000;  // 2 s
  std::vector<uint64_t> bins_;            // kBins + overflow
  uint64_t count_{0};
  double sum_ms_{0.0};
  double max_ms_{0.0};
};

}  // namespace clutterseg::daemon
