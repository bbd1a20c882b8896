#pragma once

#include <cstdint>

// Process-wide heap allocation counters. Linking alloc_counter.cc into an executable replaces
// the global operator new/delete and the C allocation functions (forwarding to glibc), so
// every allocation made by any thread is counted.
//
// Sanitizer builds (CLUTTERSEG_SANITIZER, or any ASan/TSan/MSan instrumentation) own the
// allocator themselves: there the replacement is compiled out, AllocCountingAvailable() is
// false and the counters stay zero (report them as unavailable, not as zero).
#if defined(CLUTTERSEG_NO_ALLOC_COUNTER) || defined(__SANITIZE_ADDRESS__) || \
    defined(__SANITIZE_THREAD__)
#define CLUTTERSEG_ALLOC_COUNTER_ENABLED 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define CLUTTERSEG_ALLOC_COUNTER_ENABLED 0
#endif
#endif
#ifndef CLUTTERSEG_ALLOC_COUNTER_ENABLED
#define CLUTTERSEG_ALLOC_COUNTER_ENABLED 1
#endif

namespace clutterseg::bench {

/// True when allocations are counted; false in sanitizer builds, where every count is 0.
constexpr bool AllocCountingAvailable() { return CLUTTERSEG_ALLOC_COUNTER_ENABLED != 0; }

/// Cumulative counts since process start.
struct AllocCounts {
  uint64_t news{0};     ///< calls of any global operator new / new[]
  uint64_t mallocs{0};  ///< malloc, calloc, realloc, aligned allocations (operator new included)
  uint64_t bytes{0};    ///< bytes requested from the malloc family
};

/// Current counters (all 0 when !AllocCountingAvailable()). Thread-safe (relaxed atomic
/// reads); allocates nothing.
AllocCounts CurrentAllocCounts();

/// Prints the call stack (raw addresses and exported symbols, to stderr, without allocating)
/// of the next `max_traces` allocations made by any thread; 0 stops tracing. For finding
/// where a steady-state loop allocates (resolve addresses with addr2line). Does nothing when
/// !AllocCountingAvailable().
void TraceNextAllocations(int max_traces);

/// Difference `after - before`.
AllocCounts operator-(const AllocCounts& after, const AllocCounts& before);

}  // namespace clutterseg::bench
