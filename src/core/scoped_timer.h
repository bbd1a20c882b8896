#pragma once

#include <chrono>

namespace clutterseg::core {

/// Writes the wall time of its scope to `*ms` (milliseconds, steady clock) when it ends, so a
/// stage reports its own time in its output whichever way it returns.
///
/// Thread-safety: one scope on one thread; `ms` must outlive it.
class ScopedTimer {
 public:
  explicit ScopedTimer(double* ms) : ms_(ms), start_(std::chrono::steady_clock::now()) {}
  ~ScopedTimer() {
    *ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_)
               .count();
  }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  double* ms_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace clutterseg::core
