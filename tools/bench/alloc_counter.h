#pragma once

#include <cstdint>

// Process-wide heap allocation counters. Linking alloc_counter.cc into an executable replaces
// the global operator new/delete and the C allocation functions (forwarding to glibc), so
// every allocation made by any thread is counted.
namespace clutterseg::bench {

/// Cumulative counts since process start.
struct AllocCounts {
  uint64_t news{0};     ///< calls of any global operator new / new[]
  uint64_t mallocs{0};  ///< malloc, calloc, realloc, aligned allocations (operator new included)
  uint64_t bytes{0};    ///< bytes requested from the malloc family
};

/// Current counters. Thread-safe (relaxed atomic reads); allocates nothing.
AllocCounts CurrentAllocCounts();

/// Prints the call stack (raw addresses and exported symbols, to stderr, without allocating)
/// of the next `max_traces` allocations made by any thread; 0 stops tracing. For finding
/// where a steady-state loop allocates (resolve addresses with addr2line).
void TraceNextAllocations(int max_traces);

/// Difference `after - before`.
AllocCounts operator-(const AllocCounts& after, const AllocCounts& before);

}  // namespace clutterseg::bench
