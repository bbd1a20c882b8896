#include "clutterseg/core/thread_pool.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <memory>

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#endif

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace clutterseg::core {
namespace {
thread_local const ThreadPool* t_current_pool = nullptr;
constexpr size_t kInitialRing = 64;

inline void CpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}
}  // namespace

// Lives on the stack of the ParallelFor call. Workers reach it only through queued Tasks, and
// ParallelFor returns only after every Task naming it has finished or been cancelled, all
// under mutex_: nothing touches the job after its call returned.
//
// The chunks are cut into one contiguous part per participant (the caller is participant 0).
// Each takes the chunks of its own part first, then those left in the others': successive
// calls over the same array give each thread the same stretch of it, which then is still in
// its core's cache (on the reference machine a core rewriting 3.6 MB that the other core
// wrote last takes 1.5-2.5x as long as rewriting its own).
struct ThreadPool::ParallelJob {
  static constexpr size_t kMaxParts = 16;
  struct alignas(64) Part {
    std::atomic<size_t> next{0};
    size_t end{0};
  };
  ParallelJob(FunctionRef<void(size_t, size_t)> f, size_t n_in, size_t grain_in, size_t chunks_in,
              size_t participants)
      : fn(f),
        n(n_in),
        grain(grain_in),
        chunks(chunks_in),
        num_parts(std::min(participants, kMaxParts)) {
    for (size_t p = 0; p < num_parts; ++p) {
      parts[p].next.store(p * chunks / num_parts, std::memory_order_relaxed);
      parts[p].end = (p + 1) * chunks / num_parts;
    }
  }
  FunctionRef<void(size_t, size_t)> fn;
  size_t n;
  size_t grain;
  size_t chunks;
  size_t num_parts;
  Part parts[kMaxParts];
  std::atomic<size_t> next_participant{1};  // helpers number themselves from 1
  // Queued or running helper Tasks: changed under mutex_, read without it by the caller
  // spinning for its helpers.
  std::atomic<size_t> outstanding{0};
  std::mutex error_mutex;  // taken only when a chunk throws
  size_t error_chunk{~size_t{0}};
  std::exception_ptr error;
};

ThreadPool::ThreadPool(int num_threads) : ring_(kInitialRing) {
  int n = num_threads > 0 ? num_threads : static_cast<int>(std::thread::hardware_concurrency());
  n = std::max(1, n);
#if defined(__linux__)
  cpu_set_t set;
  CPU_ZERO(&set);
  if (n > 1 && sched_getaffinity(0, sizeof set, &set) == 0) {
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(c, &set)) allowed_cpus_.push_back(c);
    }
  }
#endif
  flags_ = std::make_unique<WorkerFlags[]>(static_cast<size_t>(n));
  workers_.reserve(static_cast<size_t>(n - 1));
  for (int i = 0; i < n - 1; ++i) {
    workers_.emplace_back([this, i] { WorkerLoop(static_cast<size_t>(i)); });
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_.store(true, std::memory_order_release);
  }
  cv_.notify_all();
  for (auto& t : workers_) t.join();
}

bool ThreadPool::InWorker() const { return t_current_pool == this; }

void ThreadPool::Rest() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (count_ == 0) resting_.store(true, std::memory_order_relaxed);
}

void ThreadPool::PushLocked(Task task) {
  if (count_ == ring_.size()) {
    std::vector<Task> bigger(2 * ring_.size());
    for (size_t i = 0; i < count_; ++i) bigger[i] = std::move(ring_[(head_ + i) % ring_.size()]);
    ring_.swap(bigger);
    head_ = 0;
  }
  ring_[(head_ + count_) % ring_.size()] = std::move(task);
  ++count_;
  resting_.store(false, std::memory_order_relaxed);
  queued_.store(count_, std::memory_order_release);
}

template <typename Ready>
bool ThreadPool::SpinUntil(const Ready& ready) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline = Clock::now() + std::chrono::microseconds(kSpinMicroseconds);
  for (;;) {
    for (int i = 0; i < 64; ++i) {
      if (ready()) return true;
      CpuRelax();
    }
    if (Clock::now() >= deadline) return ready();
  }
}

void ThreadPool::SteerSleepers() {
#if defined(__linux__)
  if (allowed_cpus_.size() < 2) return;
  const int here = sched_getcpu();
  if (here < 0) return;
  bool any = false;
  for (size_t i = 0; i < workers_.size() && !any; ++i) {
    any = flags_[i].sleeping.load(std::memory_order_relaxed);
  }
  if (!any) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  for (const int c : allowed_cpus_) {
    if (c != here) CPU_SET(c, &set);
  }
  for (size_t i = 0; i < workers_.size(); ++i) {
    if (!flags_[i].sleeping.load(std::memory_order_relaxed)) continue;
    // Best effort: a failure (a CPU taken away since) leaves the worker where it was.
    if (pthread_setaffinity_np(workers_[i].native_handle(), sizeof set, &set) == 0) {
      flags_[i].steered.store(true, std::memory_order_release);
    }
  }
#endif
}

void ThreadPool::Unsteer(size_t index) {
#if defined(__linux__)
  if (!flags_[index].steered.exchange(false, std::memory_order_acq_rel)) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  for (const int c : allowed_cpus_) CPU_SET(c, &set);
  (void)pthread_setaffinity_np(pthread_self(), sizeof set, &set);
#else
  (void)index;
#endif
}

void ThreadPool::WorkerLoop(size_t index) {
  t_current_pool = this;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    if (count_ == 0 && !stopping_) {
      lock.unlock();
      // No spinning while callers run inline (ActiveCaller): no helper task can come, and
      // the cores are theirs; nor after Rest().
      SpinUntil([this] {
        return queued_.load(std::memory_order_acquire) > 0 ||
               stopping_.load(std::memory_order_acquire) ||
               resting_.load(std::memory_order_relaxed) ||
               active_callers_.load(std::memory_order_relaxed) > 1;
      });
      lock.lock();
      flags_[index].sleeping.store(true, std::memory_order_relaxed);
      cv_.wait(lock, [this] { return stopping_ || count_ > 0; });
      flags_[index].sleeping.store(false, std::memory_order_relaxed);
      if (flags_[index].steered.load(std::memory_order_acquire)) {
        lock.unlock();
        Unsteer(index);
        lock.lock();
        continue;  // the task may have been taken or cancelled meanwhile
      }
    }
    if (count_ == 0) return;  // stopping and drained
    Task task = std::move(ring_[head_]);
    ring_[head_] = Task{};
    head_ = (head_ + 1) % ring_.size();
    --count_;
    queued_.store(count_, std::memory_order_release);
    if (task.job != nullptr) {
      lock.unlock();
      RunChunks(task.job, task.job->next_participant.fetch_add(1, std::memory_order_relaxed));
      lock.lock();
      if (--task.job->outstanding == 0) done_cv_.notify_all();
    } else if (task.fn) {
      lock.unlock();
      task.fn();  // never throws: Submit wraps it in a packaged_task
      task.fn = nullptr;
      lock.lock();
    }
  }
}

void ThreadPool::RunChunks(ParallelJob* job, size_t participant) {
  for (size_t k = 0; k < job->num_parts; ++k) {
    ParallelJob::Part& part = job->parts[(participant + k) % job->num_parts];
    for (;;) {
      const size_t c = part.next.fetch_add(1, std::memory_order_relaxed);
      if (c >= part.end) break;
      RunChunk(job, c);
    }
  }
}

void ThreadPool::RunChunk(ParallelJob* job, size_t c) {
  try {
    job->fn(c * job->grain, std::min(job->n, (c + 1) * job->grain));
  } catch (...) {
    std::lock_guard<std::mutex> lock(job->error_mutex);
    if (c < job->error_chunk) {
      job->error_chunk = c;
      job->error = std::current_exception();
    }
  }
}

std::future<void> ThreadPool::Submit(std::function<void()> task) {
  auto packaged = std::make_shared<std::packaged_task<void()>>(std::move(task));
  std::future<void> result = packaged->get_future();
  if (workers_.empty()) {
    (*packaged)();
    return result;
  }
  SteerSleepers();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    PushLocked(Task{nullptr, [packaged] { (*packaged)(); }});
  }
  cv_.notify_one();
  return result;
}

void ThreadPool::ParallelFor(size_t n, size_t grain, FunctionRef<void(size_t, size_t)> fn) {
  if (n == 0) return;
  if (grain == 0) grain = 1;
  const size_t chunks = NumChunks(n, grain);
  if (chunks == 1 || workers_.empty() || InWorker() ||
      active_callers_.load(std::memory_order_relaxed) > 1) {
    for (size_t c = 0; c < chunks; ++c) fn(c * grain, std::min(n, (c + 1) * grain));
    return;
  }

  const size_t helpers = std::min(workers_.size(), chunks - 1);
  ParallelJob job(fn, n, grain, chunks, helpers + 1);
  SteerSleepers();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (size_t i = 0; i < helpers; ++i) PushLocked(Task{&job, {}});
    job.outstanding = helpers;
  }
  if (helpers == 1) {
    cv_.notify_one();
  } else {
    cv_.notify_all();
  }
  RunChunks(&job, 0);
  {
    // Every chunk is claimed now. Helpers no worker has taken yet are cancelled; those
    // running finish the chunk they hold.
    std::unique_lock<std::mutex> lock(mutex_);
    for (size_t i = 0; i < count_ && job.outstanding > 0; ++i) {
      Task& t = ring_[(head_ + i) % ring_.size()];
      if (t.job == &job) {
        t.job = nullptr;
        --job.outstanding;
      }
    }
    // Drop cancelled entries from the tail, so that a burst of calls whose workers were slow
    // to wake does not grow the ring.
    while (count_ > 0) {
      Task& tail = ring_[(head_ + count_ - 1) % ring_.size()];
      if (tail.job != nullptr || tail.fn) break;
      --count_;
    }
    queued_.store(count_, std::memory_order_release);
    if (job.outstanding.load(std::memory_order_relaxed) > 0) {
      // The helpers hold the last chunks: wait for them spinning first (see the class).
      lock.unlock();
      // Not while another caller is active: the helper may then be waiting for a core.
      const bool done = SpinUntil([&] {
                          return job.outstanding.load(std::memory_order_acquire) == 0 ||
                                 active_callers_.load(std::memory_order_relaxed) > 1;
                        }) &&
                        job.outstanding.load(std::memory_order_acquire) == 0;
      lock.lock();
      if (!done) done_cv_.wait(lock, [&] { return job.outstanding == 0; });
    }
  }
  if (job.error) std::rethrow_exception(job.error);
}

}  // namespace clutterseg::core
