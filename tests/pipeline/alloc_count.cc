// Replacement global allocation functions that count the allocations of threads that asked
// for it, in a translation unit of their own (so no call site sees both halves of a pair).
#include "tests/pipeline/alloc_count.h"

#include <cstddef>
#include <cstdlib>
#include <new>

namespace {
thread_local bool t_counting = false;
thread_local int64_t t_count = 0;
}  // namespace

void* operator new(std::size_t size) {
  if (t_counting) ++t_count;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return ::operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace clutterseg::pipeline::tracking_test {

void CountAllocations(bool on) {
  if (on) t_count = 0;
  t_counting = on;
}

int64_t CountedAllocations() { return t_count; }

}  // namespace clutterseg::pipeline::tracking_test
