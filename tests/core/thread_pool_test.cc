#include "clutterseg/core/thread_pool.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <new>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "tests/testing/process_cpu.h"

// Counts every operator new of this test binary (malloc itself is left alone). Not under the
// sanitizers, which replace the allocator themselves and check new/delete pairing.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define CLUTTERSEG_COUNT_NEW 0
#else
#define CLUTTERSEG_COUNT_NEW 1
#endif
namespace {
std::atomic<long> g_news{0};
}  // namespace

#if CLUTTERSEG_COUNT_NEW
void* operator new(std::size_t size) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#endif

namespace clutterseg::core {
namespace {

// Sums per chunk and combines in chunk order: must give the same bits for any pool size.
double ChunkedSum(ThreadPool* pool, const std::vector<double>& values) {
  const size_t grain = 1000;
  std::vector<double> partial(ThreadPool::NumChunks(values.size(), grain), 0.0);
  pool->ParallelFor(values.size(), grain, [&](size_t b, size_t e) {
    double s = 0.0;
    for (size_t i = b; i < e; ++i) s += values[i];
    partial[b / grain] = s;
  });
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

TEST(ThreadPool, CoversEveryIndexExactlyOnce) {
  for (int threads : {1, 2, 4, 7}) {
    ThreadPool dut(threads);
    EXPECT_EQ(dut.num_threads(), threads);
    std::vector<std::atomic<int>> hits(10007);
    dut.ParallelFor(hits.size(), 64, [&](size_t b, size_t e) {
      for (size_t i = b; i < e; ++i) hits[i].fetch_add(1);
    });
    for (size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i].load(), 1) << "index " << i;
  }
}

TEST(ThreadPool, ChunkedReductionIsIdenticalForAnyThreadCount) {
  std::vector<double> values(123457);
  for (size_t i = 0; i < values.size(); ++i) values[i] = 1.0 / (1.0 + static_cast<double>(i % 977));
  ThreadPool one(1);
  const double reference = ChunkedSum(&one, values);
  for (int threads : {2, 3, 8}) {
    ThreadPool dut(threads);
    for (int rep = 0; rep < 5; ++rep) EXPECT_EQ(ChunkedSum(&dut, values), reference);
  }
}

TEST(ThreadPool, RethrowsTheFirstChunkException) {
  ThreadPool dut(3);
  EXPECT_THROW(dut.ParallelFor(100, 10,
                               [](size_t b, size_t) {
                                 if (b == 50) throw std::runtime_error("chunk 5 failed");
                               }),
               std::runtime_error);
  // The pool stays usable after a failure.
  std::atomic<int> n{0};
  dut.ParallelFor(10, 1, [&](size_t, size_t) { n++; });
  EXPECT_EQ(n.load(), 10);
}

TEST(ThreadPool, NestedParallelForRunsInlineWithoutDeadlock) {
  ThreadPool dut(2);
  std::atomic<int> inner{0};
  dut.ParallelFor(8, 1,
                  [&](size_t, size_t) { dut.ParallelFor(4, 1, [&](size_t, size_t) { inner++; }); });
  EXPECT_EQ(inner.load(), 32);
}

TEST(ThreadPool, SubmitRunsTasksAndCarriesExceptions) {
  ThreadPool dut(2);
  std::atomic<int> ran{0};
  std::vector<std::future<void>> futures;
  for (int i = 0; i < 20; ++i) futures.push_back(dut.Submit([&] { ran++; }));
  for (auto& f : futures) f.get();
  EXPECT_EQ(ran.load(), 20);
  auto bad = dut.Submit([] { throw std::logic_error("task failed"); });
  EXPECT_THROW(bad.get(), std::logic_error);
}

TEST(ThreadPool, ParallelForAllocatesNothingAtSteadyState) {
  if (!CLUTTERSEG_COUNT_NEW) GTEST_SKIP() << "operator new is not counted under the sanitizers";
  ThreadPool dut(3);
  std::vector<double> out(4096, 0.0);
  auto body = [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) out[i] += 1.0;
  };
  dut.ParallelFor(out.size(), 64, body);  // warm-up: the workers' first wake-up
  const long before = g_news.load();
  for (int rep = 0; rep < 200; ++rep) dut.ParallelFor(out.size(), 64, body);
  EXPECT_EQ(g_news.load() - before, 0);
  for (double v : out) ASSERT_EQ(v, 201.0);
}

TEST(ThreadPool, CallersSharingThePoolDoNotInterfere) {
  // Two threads (two pipelined segmenters) fan out on one pool at the same time: each call
  // must see exactly its own chunks, and both must return.
  ThreadPool dut(2);
  auto caller = [&](std::vector<int>* hits) {
    for (int rep = 0; rep < 300; ++rep) {
      dut.ParallelFor(hits->size(), 7, [&](size_t b, size_t e) {
        for (size_t i = b; i < e; ++i) ++(*hits)[i];
      });
    }
  };
  std::vector<int> a(100, 0), b(53, 0);
  std::thread ta(caller, &a), tb(caller, &b);
  ta.join();
  tb.join();
  for (int v : a) ASSERT_EQ(v, 300);
  for (int v : b) ASSERT_EQ(v, 300);
}

TEST(ThreadPool, RunsInlineWhileTwoCallersAreActive) {
  ThreadPool dut(4);
  auto chunk_threads = [&] {
    std::vector<std::thread::id> ids(64);
    dut.ParallelFor(ids.size(), 1, [&](size_t b, size_t) {
      // Long enough that idle workers would take chunks if the call fanned out.
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      ids[b] = std::this_thread::get_id();
    });
    return ids;
  };
  {
    ThreadPool::ActiveCaller first(&dut);
    ThreadPool::ActiveCaller second(&dut);
    for (const std::thread::id id : chunk_threads()) EXPECT_EQ(id, std::this_thread::get_id());
  }
  // With at most one active caller the call fans out again: some chunk runs on a worker.
  ThreadPool::ActiveCaller only(&dut);
  const std::vector<std::thread::id> ids = chunk_threads();
  EXPECT_TRUE(std::any_of(ids.begin(), ids.end(),
                          [](std::thread::id id) { return id != std::this_thread::get_id(); }));
  ThreadPool::ActiveCaller none(nullptr);  // a null pool is allowed
}

TEST(ThreadPool, UnevenChunksRunOnceEachWhileThreadsTakeOverOthersParts) {
  // The chunks of the first part are slow: the other threads finish their own parts and
  // then take what is left of it. Every chunk must still run exactly once.
  for (int threads : {2, 3, 5}) {
    ThreadPool dut(threads);
    for (int rep = 0; rep < 20; ++rep) {
      std::vector<std::atomic<int>> hits(97);
      dut.ParallelFor(hits.size(), 1, [&](size_t b, size_t) {
        if (b < hits.size() / 4) std::this_thread::sleep_for(std::chrono::microseconds(100));
        hits[b].fetch_add(1);
      });
      for (size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i].load(), 1) << "chunk " << i;
    }
  }
}

using clutterseg::testing::ProcessCpuMs;

TEST(ThreadPool, IdleWorkersStopSpinningAndBlock) {
  // After a call the workers spin for a moment (the next call of a frame comes soon), then
  // block: an idle pool must not keep burning a core.
  ThreadPool dut(2);
  std::vector<double> out(1 << 16, 0.0);
  dut.ParallelFor(out.size(), 1024, [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) out[i] = static_cast<double>(i);
  });
  const auto spin = std::chrono::microseconds(ThreadPool::kSpinMicroseconds);
  std::this_thread::sleep_for(10 * spin);  // past the spin: the worker blocked
  const double cpu0 = ProcessCpuMs();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const double idle_cpu_ms = ProcessCpuMs() - cpu0;
  // A spinning worker would use about 200 ms of CPU here.
  EXPECT_LT(idle_cpu_ms, 40.0);
  EXPECT_EQ(out.back(), static_cast<double>(out.size() - 1));
}

// Rest(): the idle workers block at once instead of spinning out kSpinMicroseconds after the
// call (20 rounds of spinning would use about 40 ms of CPU), and the next call wakes them and
// still covers every chunk once.
TEST(ThreadPool, RestBlocksIdleWorkersAtOnceAndTheNextCallWakesThem) {
  ThreadPool dut(2);
  const auto spin = std::chrono::microseconds(ThreadPool::kSpinMicroseconds);
  double idle_cpu_ms = 0.0;
  for (int round = 0; round < 20; ++round) {
    // The caller's chunk waits for the worker's, so the worker runs (and would spin after).
    std::atomic<bool> worker_ran{false};
    dut.ParallelFor(2, 1, [&](size_t b, size_t) {
      if (b == 1) {
        worker_ran.store(true);
        return;
      }
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (!worker_ran.load() && std::chrono::steady_clock::now() < deadline) {
      }
    });
    ASSERT_TRUE(worker_ran.load()) << "round " << round;
    dut.Rest();
    const double cpu0 = ProcessCpuMs();
    std::this_thread::sleep_for(2 * spin);
    idle_cpu_ms += ProcessCpuMs() - cpu0;
  }
  EXPECT_LT(idle_cpu_ms, 10.0);
  // Work queued after a rest wakes the worker: it still takes its part.
  std::atomic<int> worker_chunks{0};
  dut.ParallelFor(2, 1, [&](size_t b, size_t) {
    if (b == 1) {
      worker_chunks.fetch_add(dut.InWorker() ? 1 : 0);
      return;
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (worker_chunks.load() == 0 && std::chrono::steady_clock::now() < deadline) {
    }
  });
  EXPECT_EQ(worker_chunks.load(), 1);
}

// A worker woken from its block is kept off its caller's CPU only until it runs: inside its
// chunk its affinity is the process's again, and it ran on another CPU than its caller (the
// caller waits in its own chunk until the worker's has run, so both ran at once). A pool made
// on a thread allowed one CPU steers nothing and still covers every chunk.
TEST(ThreadPool, WokenWorkerRunsBesideItsCallerWithItsCpusRestored) {
  cpu_set_t process;
  CPU_ZERO(&process);
  ASSERT_EQ(sched_getaffinity(0, sizeof process, &process), 0);
  if (CPU_COUNT(&process) < 2) GTEST_SKIP() << "needs two CPUs";
  ThreadPool dut(2);
  const auto spin = std::chrono::microseconds(ThreadPool::kSpinMicroseconds);
  for (int round = 0; round < 3; ++round) {
    std::this_thread::sleep_for(10 * spin);  // the worker blocks
    std::atomic<int> worker_cpu{-1};
    std::atomic<bool> worker_mask_full{false};
    int caller_cpu = -1;
    dut.ParallelFor(2, 1, [&](size_t b, size_t) {
      if (b == 0) {
        caller_cpu = sched_getcpu();
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
        while (worker_cpu.load() < 0 && std::chrono::steady_clock::now() < deadline) {
        }
        return;
      }
      cpu_set_t mine;
      CPU_ZERO(&mine);
      pthread_getaffinity_np(pthread_self(), sizeof mine, &mine);
      worker_mask_full.store(CPU_EQUAL(&mine, &process) != 0);
      worker_cpu.store(sched_getcpu());
    });
    ASSERT_GE(worker_cpu.load(), 0) << "round " << round << ": the worker never ran chunk 1";
    EXPECT_NE(worker_cpu.load(), caller_cpu) << "round " << round;
    EXPECT_TRUE(worker_mask_full.load()) << "round " << round << ": the worker stayed steered";
  }

  // One CPU allowed: nothing to steer to.
  std::thread single([&] {
    cpu_set_t one;
    CPU_ZERO(&one);
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(c, &process)) {
        CPU_SET(c, &one);
        break;
      }
    }
    ASSERT_EQ(pthread_setaffinity_np(pthread_self(), sizeof one, &one), 0);
    ThreadPool pinned(2);
    std::this_thread::sleep_for(10 * spin);
    std::vector<int> hits(64, 0);
    pinned.ParallelFor(hits.size(), 4, [&](size_t b, size_t e) {
      for (size_t i = b; i < e; ++i) ++hits[i];
    });
    EXPECT_EQ(std::count(hits.begin(), hits.end(), 1), 64);
  });
  single.join();
}

}  // namespace
}  // namespace clutterseg::core
