#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "clutterseg/core/function_ref.h"

namespace clutterseg::core {

/// A fixed-size pool of std::threads for work inside a frame (ParallelFor) and across frames
/// (Submit). Work is split into chunks whose boundaries depend only on the problem size and
/// the grain, never on the number of threads, so per-chunk results combined in chunk order
/// are identical for any pool size.
///
/// An idle worker, and a ParallelFor caller waiting for its helpers, spin for up to
/// kSpinMicroseconds before they block: the stages of
/// a frame call ParallelFor dozens of times with serial work of up to a millisecond between
/// the calls, and waking a blocked thread costs 30-110 us on the 2-core reference machine (a
/// virtual machine), as much as a small stage's work. A worker that found nothing within that
/// time blocks, so an idle pool costs no CPU; while more than one ActiveCaller runs (nothing
/// fans out, and every core has a caller) nobody spins. Yielding inside the spin was measured
/// and rejected: it cost the daemon 15% of its replay rate on full rooms.
///
/// A blocked worker woken for a ParallelFor is first kept off the caller's CPU (its affinity
/// set to the process's CPUs without the caller's, on Linux when more than one is allowed).
/// Where the kernel knows no cache shared between the CPUs (the reference machine exposes
/// none) it queues a woken thread on the waker's CPU even while another CPU idles, and a
/// balancing tick (4 ms) passes before it moves: the helper then first takes time from its own
/// caller. Measured there with `perf sched`: woken helpers waiting up to 4.2 ms beside an idle
/// CPU, on the frames that made the 30 Hz tail.
///
/// Thread-safety: all methods may be called from any thread. ParallelFor called from inside a
/// pool worker runs inline on that worker (no nested fan-out, no deadlock).
class ThreadPool {
 public:
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;
  ThreadPool(ThreadPool&&) = delete;
  ThreadPool& operator=(ThreadPool&&) = delete;

  /// Starts `num_threads - 1` workers (the caller of ParallelFor is the last one). 0 means
  /// std::thread::hardware_concurrency(); 1 means everything runs on the calling thread.
  explicit ThreadPool(int num_threads = 0);
  /// Finishes queued tasks, then joins the workers.
  ~ThreadPool();

  /// How long an idle worker, or a caller waiting for its helpers, spins before it blocks, us
  /// (longer than the serial stretches between a frame's ParallelFor calls).
  static constexpr int kSpinMicroseconds = 2000;

  /// Total threads that execute ParallelFor chunks (workers + caller).
  int num_threads() const { return static_cast<int>(workers_.size()) + 1; }

  /// Calls `fn(begin, end)` for the chunks [k*grain, min(n, (k+1)*grain)) of [0, n), in
  /// parallel, and returns when all are done. If any chunk throws, the first exception (in
  /// chunk order) is rethrown here after all chunks finished.
  void ParallelFor(size_t n, size_t grain, FunctionRef<void(size_t, size_t)> fn);

  /// Number of chunks ParallelFor uses for (n, grain).
  static size_t NumChunks(size_t n, size_t grain) {
    return grain == 0 ? 0 : (n + grain - 1) / grain;
  }

  /// Queues `task` to run on a worker (or inline when the pool has no worker) and returns its
  /// future; an exception thrown by the task is stored in the future.
  std::future<void> Submit(std::function<void()> task);

  /// True when called from one of this pool's worker threads.
  bool InWorker() const;

  /// Says that no ParallelFor or Submit is due soon (a frame is done and the next has not
  /// arrived): idle workers block now instead of spinning out kSpinMicroseconds, until work
  /// is queued again. A spinning worker holds its core, and a thread of the process woken
  /// meanwhile (a sink publishing the frame just done) can be queued behind it for the rest of
  /// the spin: measured on the reference machine, 1.6 ms on a quarter of the frames of a 30 Hz
  /// camera. The next call's helpers then pay a blocked thread's wake-up instead.
  void Rest();

  /// Marks a long-running caller (e.g. a thread segmenting one frame) as active for its
  /// lifetime. While more than one caller is active, ParallelFor runs inline: each active
  /// caller already keeps a core busy, and fanning out would only add threads per core. As
  /// soon as one is left, its ParallelFor calls fan out again. Results do not change.
  class ActiveCaller {
   public:
    explicit ActiveCaller(ThreadPool* pool) : pool_(pool) {
      if (pool_ != nullptr) pool_->active_callers_.fetch_add(1, std::memory_order_relaxed);
    }
    ~ActiveCaller() {
      if (pool_ != nullptr) pool_->active_callers_.fetch_sub(1, std::memory_order_relaxed);
    }
    ActiveCaller(const ActiveCaller&) = delete;
    ActiveCaller& operator=(const ActiveCaller&) = delete;

   private:
    ThreadPool* pool_;
  };

 private:
  struct ParallelJob;
  // A queued unit of work: a ParallelFor helper (job set) or a submitted task (fn set). A
  // helper whose ParallelFor finished before a worker took it is cancelled (job reset).
  struct Task {
    ParallelJob* job{nullptr};
    std::function<void()> fn;
  };

  void WorkerLoop(size_t index);
  // Keeps the blocked workers off the calling thread's CPU before they are woken (see the
  // class comment); does nothing when the process may use one CPU only.
  void SteerSleepers();
  // Gives a woken worker the process's CPUs back (it keeps running where it is).
  void Unsteer(size_t index);
  // Spins until `ready()` or kSpinMicroseconds passed; returns ready().
  template <typename Ready>
  static bool SpinUntil(const Ready& ready);
  void PushLocked(Task task);  // mutex_ held; grows the ring only when it is full
  static void RunChunks(ParallelJob* job, size_t participant);
  static void RunChunk(ParallelJob* job, size_t chunk);

  std::vector<std::thread> workers_;
  // Per worker: `sleeping` while blocked in cv_ (set and cleared by the worker under mutex_,
  // read by callers without it: a worker falling asleep meanwhile is simply not steered);
  // `steered` once a caller restricted its CPUs, until the woken worker restores them (so it
  // is restricted only for the wake-up's placement).
  struct WorkerFlags {
    std::atomic<bool> sleeping{false};
    std::atomic<bool> steered{false};
  };
  std::unique_ptr<WorkerFlags[]> flags_;
  std::vector<int> allowed_cpus_;  // the process's CPUs at construction (Linux), ascending
  std::mutex mutex_;
  std::condition_variable cv_;       // work queued or stopping
  std::condition_variable done_cv_;  // a ParallelFor helper finished
  std::vector<Task> ring_;           // circular queue, capacity ring_.size()
  size_t head_{0};
  size_t count_{0};
  std::atomic<size_t> queued_{0};       // count_, written under mutex_, read by spinning workers
  std::atomic<bool> stopping_{false};   // set under mutex_; spinning workers read it without
  std::atomic<bool> resting_{false};    // Rest() until the next task is queued (under mutex_)
  std::atomic<int> active_callers_{0};  // see ActiveCaller
};

/// Calls `fn(begin, end)` for the chunks [k*grain, min(n, (k+1)*grain)) of [0, n) (grain > 0):
/// through `pool`'s ParallelFor, or in chunk order on the calling thread when `pool` is null
/// or there is a single chunk. The chunks are the same either way, so results combined in
/// chunk order do not depend on the pool.
template <typename Fn>
void ForChunks(ThreadPool* pool, size_t n, size_t grain, const Fn& fn) {
  if (n == 0) return;
  if (pool == nullptr || n <= grain) {
    for (size_t b = 0; b < n; b += grain) fn(b, std::min(n, b + grain));
    return;
  }
  pool->ParallelFor(n, grain, fn);
}

/// Counts over the chunks of [0, n) as ForChunks runs them: `fn(begin, end, table)` adds into
/// `table`, `size` counters of its chunk's own (zeroed first; `scratch` holds them), and the
/// chunks' tables are then added into `out` (`size` counters, not zeroed here). Counts are
/// sums, so `out` does not depend on the pool.
template <typename Fn>
void CountInChunks(ThreadPool* pool, size_t n, size_t grain, size_t size,
                   std::vector<uint32_t>* scratch, uint32_t* out, const Fn& fn) {
  const size_t chunks = ThreadPool::NumChunks(n, grain);
  scratch->assign(chunks * size, 0u);
  uint32_t* tables = scratch->data();
  ForChunks(pool, n, grain, [&](size_t b, size_t e) { fn(b, e, tables + (b / grain) * size); });
  for (size_t k = 0; k < chunks; ++k) {
    const uint32_t* t = tables + k * size;
    for (size_t j = 0; j < size; ++j) out[j] += t[j];
  }
}

}  // namespace clutterseg::core
