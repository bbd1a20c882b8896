#include "core/thread_pool.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <memory>

namespace clutterseg::core {
namespace {
thread_local const ThreadPool* t_current_pool = nullptr;
}  // namespace

ThreadPool::ThreadPool(int num_threads) {
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

void ThreadPool::WorkerLoop() {
  t_current_pool = this;
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping and drained
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    task();  // tasks never throw: Submit and ParallelFor wrap them
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
    queue_.emplace_back([packaged] { (*packaged)(); });
  }
  cv_.notify_one();
  return result;
}

void ThreadPool::ParallelFor(size_t n, size_t grain,
                             const std::function<void(size_t, size_t)>& fn) {
  if (n == 0) return;
  if (grain == 0) grain = 1;
  const size_t chunks = NumChunks(n, grain);
  if (chunks == 1 || workers_.empty() || InWorker()) {
    for (size_t c = 0; c < chunks; ++c) fn(c * grain, std::min(n, (c + 1) * grain));
    return;
  }

  struct Job {
    std::atomic<size_t> next{0};
    std::atomic<size_t> done{0};
    std::vector<std::exception_ptr> errors;
    std::mutex mutex;
    std::condition_variable cv;
  };
  auto job = std::make_shared<Job>();
  job->errors.resize(chunks);

  auto run = [job, chunks, grain, n, &fn] {
    for (;;) {
      const size_t c = job->next.fetch_add(1);
      if (c >= chunks) return;
      try {
        fn(c * grain, std::min(n, (c + 1) * grain));
      } catch (...) {
        job->errors[c] = std::current_exception();
      }
      if (job->done.fetch_add(1) + 1 == chunks) {
        std::lock_guard<std::mutex> lock(job->mutex);
        job->cv.notify_all();
      }
    }
  };

  const size_t helpers = std::min(workers_.size(), chunks - 1);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (size_t i = 0; i < helpers; ++i) queue_.emplace_back(run);
  }
  cv_.notify_all();
  run();
  {
    std::unique_lock<std::mutex> lock(job->mutex);
    job->cv.wait(lock, [&] { return job->done.load() == chunks; });
  }
  for (auto& e : job->errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace clutterseg::core
