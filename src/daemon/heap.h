#pragma once

#include <string>

namespace clutterseg::daemon {

/// How the daemon's process heap is prepared for bounded latency (key
/// `processing.prefault_heap_mb`).
struct HeapParams {
  /// MiB of heap touched at start-up and kept for the whole run; 0 leaves glibc's defaults.
  /// Each lane's work buffers grow to the largest frame it has met, and growing means pages
  /// the kernel has not handed out yet: on the reference machine they cost about 18 us each,
  /// and the first cluttered frame a lane meets took 34-47 ms instead of 22. With a prefaulted
  /// heap that growth finds pages already in place. The process's resident size grows to at
  /// least this much.
  int prefault_mb{128};

  /// @throws std::invalid_argument naming the key and value.
  void ValidateOrThrow() const;
};

/// Makes every later allocation of the process come from one heap (glibc: one arena, no
/// mmap'd chunks, never trimmed) and touches its first `params.prefault_mb` MiB, so that memory
/// freed and allocated again during the run is never handed back to the kernel and faulted in
/// anew. The real-time Linux recipe for dynamic memory, without locking it (mlockall needs a
/// privilege the daemon does not ask for). Call it once, early in main, before the threads
/// that allocate start. Returns false with `*problem` set when glibc refuses a setting or the
/// memory cannot be had; the process then runs with the heap as it is. Does nothing in a
/// sanitizer build (the sanitizer's allocator ignores glibc's settings).
/// Thread-safety: not thread-safe; call before starting threads.
bool PrepareHeap(const HeapParams& params, std::string* problem);

}  // namespace clutterseg::daemon
