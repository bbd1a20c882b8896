#include "clutterseg/daemon/heap.h"

#include <malloc.h>

#include <climits>
#include <cstdlib>

#include "clutterseg/core/param_check.h"

namespace clutterseg::daemon {

void HeapParams::ValidateOrThrow() const {
  core::ParamCheck("processing").InRange("prefault_heap_mb", prefault_mb, 0, 65536, "MiB");
}

bool PrepareHeap(const HeapParams& params, std::string* problem) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  // The sanitizers bring their own allocator, which ignores glibc's settings.
  (void)params;
  (void)problem;
  return true;
#else
  if (params.prefault_mb == 0) return true;
  // One arena for every thread, every chunk from it (no mmap'd chunks, which free() unmaps),
  // and no trimming of its top: freed memory stays with the process.
  if (mallopt(M_ARENA_MAX, 1) != 1 || mallopt(M_MMAP_MAX, 0) != 1 ||
      mallopt(M_TRIM_THRESHOLD, INT_MAX) != 1) {
    *problem = "glibc refused a malloc setting (M_ARENA_MAX, M_MMAP_MAX, M_TRIM_THRESHOLD)";
    return false;
  }
  const size_t bytes = static_cast<size_t>(params.prefault_mb) << 20;
  auto* block = static_cast<volatile char*>(std::malloc(bytes));
  if (block == nullptr) {
    *problem = "cannot allocate " + std::to_string(params.prefault_mb) + " MiB to prefault";
    return false;
  }
  // One write per page faults it in; the volatile writes cannot be optimised away.
  for (size_t i = 0; i < bytes; i += 4096) block[i] = 0;
  std::free(const_cast<char*>(block));
  return true;
#endif
}

}  // namespace clutterseg::daemon
