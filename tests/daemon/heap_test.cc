#include "clutterseg/daemon/heap.h"

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sys/resource.h>

#include "tests/testing/expect_invalid_argument.h"

namespace clutterseg::daemon {
namespace {

long MinorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

// Page faults taken by allocating and writing 32 MiB the way a growing work buffer does.
long FaultsOfA32MiBBuffer() {
  const long before = MinorFaults();
  std::vector<float> buffer(size_t{8} << 20, 1.f);
  volatile float sink = buffer[buffer.size() / 2];
  (void)sink;
  return MinorFaults() - before;
}

// Each case runs in a process of its own (a death test re-runs the binary), since the heap
// settings are the whole process's.
TEST(PrepareHeap, GrowingBuffersFindTheirPagesInPlace) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers replace glibc's allocator (PrepareHeap does nothing there)";
#endif
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  // Without it, 32 MiB of new buffer are 8192 pages faulted in while the buffer is written.
  EXPECT_EXIT(
      {
        const long faults = FaultsOfA32MiBBuffer();
        std::fprintf(stderr, "faults %ld\n", faults);
        std::exit(faults >= 4096 ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "faults");
  // With 64 MiB prefaulted, nearly none.
  EXPECT_EXIT(
      {
        std::string problem;
        HeapParams params;
        params.prefault_mb = 64;
        if (!PrepareHeap(params, &problem)) std::exit(2);
        const long faults = FaultsOfA32MiBBuffer();
        std::fprintf(stderr, "faults %ld\n", faults);
        std::exit(faults < 256 ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "faults");
}

TEST(PrepareHeap, ZeroLeavesTheHeapAloneAndTheKeyIsChecked) {
  std::string problem;
  HeapParams off;
  off.prefault_mb = 0;
  EXPECT_TRUE(PrepareHeap(off, &problem));
  EXPECT_TRUE(problem.empty());
  HeapParams bad;
  bad.prefault_mb = -1;
  testing::ExpectInvalidArgumentNaming([&] { bad.ValidateOrThrow(); },
                                       "processing.prefault_heap_mb");
}

}  // namespace
}  // namespace clutterseg::daemon
