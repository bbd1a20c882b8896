// Replacement allocation functions that count calls and forward to glibc's allocator.
#include "tools/bench/alloc_counter.h"

#if !CLUTTERSEG_ALLOC_COUNTER_ENABLED
// Sanitizer build: the sanitizer runtime replaces malloc/free itself, and forwarding to
// glibc's __libc_* functions behind its back crashes. Nothing is replaced or counted.
namespace clutterseg::bench {

void TraceNextAllocations(int /*max_traces*/) {}

AllocCounts CurrentAllocCounts() { return AllocCounts{}; }

AllocCounts operator-(const AllocCounts& after, const AllocCounts& before) {
  return AllocCounts{after.news - before.news, after.mallocs - before.mallocs,
                     after.bytes - before.bytes};
}

}  // namespace clutterseg::bench
#else

#include <execinfo.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <new>

extern "C" {
void* __libc_malloc(size_t size);
void* __libc_calloc(size_t n, size_t size);
void* __libc_realloc(void* p, size_t size);
void* __libc_memalign(size_t alignment, size_t size);
void __libc_free(void* p);
}

namespace clutterseg::bench {
namespace {

std::atomic<uint64_t> g_news{0};
std::atomic<uint64_t> g_mallocs{0};
std::atomic<uint64_t> g_bytes{0};
std::atomic<int> g_traces_left{0};
thread_local bool t_in_trace = false;

void Trace(size_t size) {
  if (t_in_trace) return;
  if (g_traces_left.fetch_sub(1, std::memory_order_relaxed) <= 0) {
    g_traces_left.store(0, std::memory_order_relaxed);
    return;
  }
  t_in_trace = true;
  void* frames[24];
  const int n = backtrace(frames, 24);
  char line[64];
  const int len = std::snprintf(line, sizeof(line), "--- allocation of %zu bytes:\n", size);
  if (len > 0) (void)!write(2, line, static_cast<size_t>(len));
  backtrace_symbols_fd(frames, n, 2);
  t_in_trace = false;
}

inline void CountMalloc(size_t size) {
  g_mallocs.fetch_add(1, std::memory_order_relaxed);
  g_bytes.fetch_add(size, std::memory_order_relaxed);
  if (g_traces_left.load(std::memory_order_relaxed) > 0) Trace(size);
}

void* NewOrThrow(size_t size) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  void* p = std::malloc(size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

void* AlignedNewOrThrow(size_t size, std::align_val_t align) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  CountMalloc(size);
  void* p = __libc_memalign(static_cast<size_t>(align), size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

}  // namespace

void TraceNextAllocations(int max_traces) {
  if (max_traces > 0) {
    // The first backtrace() loads libgcc (which allocates): do it before tracing starts.
    void* frames[2];
    t_in_trace = true;
    backtrace(frames, 2);
    t_in_trace = false;
  }
  g_traces_left.store(max_traces, std::memory_order_relaxed);
}

AllocCounts CurrentAllocCounts() {
  AllocCounts c;
  c.news = g_news.load(std::memory_order_relaxed);
  c.mallocs = g_mallocs.load(std::memory_order_relaxed);
  c.bytes = g_bytes.load(std::memory_order_relaxed);
  return c;
}

AllocCounts operator-(const AllocCounts& after, const AllocCounts& before) {
  return AllocCounts{after.news - before.news, after.mallocs - before.mallocs,
                     after.bytes - before.bytes};
}

}  // namespace clutterseg::bench

using clutterseg::bench::AlignedNewOrThrow;
using clutterseg::bench::CountMalloc;
using clutterseg::bench::NewOrThrow;

extern "C" {

void* malloc(size_t size) {
  CountMalloc(size);
  return __libc_malloc(size);
}

void* calloc(size_t n, size_t size) {
  CountMalloc(n * size);
  return __libc_calloc(n, size);
}

void* realloc(void* p, size_t size) {
  CountMalloc(size);
  return __libc_realloc(p, size);
}

void free(void* p) { __libc_free(p); }

void* memalign(size_t alignment, size_t size) {
  CountMalloc(size);
  return __libc_memalign(alignment, size);
}

void* aligned_alloc(size_t alignment, size_t size) {
  CountMalloc(size);
  return __libc_memalign(alignment, size);
}

int posix_memalign(void** out, size_t alignment, size_t size) {
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  CountMalloc(size);
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}

}  // extern "C"

void* operator new(size_t size) { return NewOrThrow(size); }
void* operator new[](size_t size) { return NewOrThrow(size); }
void* operator new(size_t size, const std::nothrow_t&) noexcept {
  try {
    return NewOrThrow(size);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](size_t size, const std::nothrow_t&) noexcept {
  try {
    return NewOrThrow(size);
  } catch (...) {
    return nullptr;
  }
}
void* operator new(size_t size, std::align_val_t align) { return AlignedNewOrThrow(size, align); }
void* operator new[](size_t size, std::align_val_t align) { return AlignedNewOrThrow(size, align); }
void* operator new(size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {
  try {
    return AlignedNewOrThrow(size, align);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {
  try {
    return AlignedNewOrThrow(size, align);
  } catch (...) {
    return nullptr;
  }
}
void operator delete(void* p) noexcept { __libc_free(p); }
void operator delete[](void* p) noexcept { __libc_free(p); }
void operator delete(void* p, size_t) noexcept { __libc_free(p); }
void operator delete[](void* p, size_t) noexcept { __libc_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  __libc_free(p);
}

#endif  // CLUTTERSEG_ALLOC_COUNTER_ENABLED
