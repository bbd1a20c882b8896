#include "clutterseg/core/thread_pool.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <memory>

namespace clutterseg::core {
namespace {
thread_local const ThreadPool* t_current_pool = nullptr;
constexpr size_t kInitialRing = 64;
}  // namespace

// Lives on the stack of the ParallelFor call. Workers reach it only through queued Tasks, and
// ParallelFor returns only after every Task naming it has finished or been cancelled, all
// under mutex_: nothing touches the job after its call returned.
struct ThreadPool::ParallelJob {
  FunctionRef<void(size_t, size_t)> fn;
  size_t n;
  size_t grain;
  size_t chunks;
  std::atomic<size_t> next{0};
  size_t outstanding{0};   // queued or running helper Tasks; guarded by mutex_
  std::mutex error_mutex;  // taken only when a chunk throws
  size_t error_chunk{~size_t{0}};
  std::exception_ptr error;
};

ThreadPool::ThreadPool(int num_threads) : ring_(kInitialRing) {
  int n = num_threads > 0 ? num_threads : static_cast<int>(std::thread::hardware_concurrency());
  n = std::max(1, n);
  workers_.reserve(static_cast<size_t>(n - 1));
  for (int i = 0; i < n - 1; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  for (auto& t : workers_) t.join();
}

bool ThreadPool::InWorker() const { return t_current_pool == this; }

void ThreadPool::PushLocked(Task task) {
  if (count_ == ring_.size()) {
    std::vector<Task> bigger(2 * ring_.size());
    for (size_t i = 0; i < count_; ++i) bigger[i] = std::move(ring_[(head_ + i) % ring_.size()]);
    ring_.swap(bigger);
    head_ = 0;
  }
  ring_[(head_ + count_) % ring_.size()] = std::move(task);
  ++count_;
}

void ThreadPool::WorkerLoop() {
  t_current_pool = this;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    cv_.wait(lock, [this] { return stopping_ || count_ > 0; });
    if (count_ == 0) return;  // stopping and drained
    Task task = std::move(ring_[head_]);
    ring_[head_] = Task{};
    head_ = (head_ + 1) % ring_.size();
    --count_;
    if (task.job != nullptr) {
      lock.unlock();
      RunChunks(task.job);
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

void ThreadPool::RunChunks(ParallelJob* job) {
  for (;;) {
    const size_t c = job->next.fetch_add(1, std::memory_order_relaxed);
    if (c >= job->chunks) return;
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
}

std::future<void> ThreadPool::Submit(std::function<void()> task) {
  auto packaged = std::make_shared<std::packaged_task<void()>>(std::move(task));
  std::future<void> result = packaged->get_future();
  if (workers_.empty()) {
    (*packaged)();
    return result;
  }
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

  ParallelJob job{fn, n, grain, chunks};
  const size_t helpers = std::min(workers_.size(), chunks - 1);
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
  RunChunks(&job);
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
    done_cv_.wait(lock, [&] { return job.outstanding == 0; });
  }
  if (job.error) std::rethrow_exception(job.error);
}

}  // namespace clutterseg::core
