#pragma once

#include <time.h>

namespace clutterseg::testing {

/// CPU time of the whole process (every thread) so far, ms: what a spinning thread costs,
/// which load on the machine can only lower (a preempted spinner uses less).
inline double ProcessCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

}  // namespace clutterseg::testing
