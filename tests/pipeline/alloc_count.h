#pragma once

#include <cstdint>

namespace clutterseg::pipeline::tracking_test {

// The test binary replaces the global operator new (alloc_count.cc): while counting is on,
// it counts the calling thread's allocations.

// Starts (resetting the count) or stops counting on the calling thread.
void CountAllocations(bool on);
// Allocations counted on the calling thread since counting last started.
int64_t CountedAllocations();

}  // namespace clutterseg::pipeline::tracking_test
