#include "clutterseg/pipeline/frame_runner.h"

#include <pthread.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <exception>
#include <mutex>
#include <thread>

#include "clutterseg/core/param_check.h"

namespace clutterseg::pipeline {

void FrameRunnerParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("pipeline_depth", pipeline_depth, 1, 8);
  check.InRange("threads", threads, 0, 256, "(0 = cores)");
}

namespace {

// One lane. Fields marked (m) are guarded by Impl::mutex.
struct LaneState {
  std::thread thread;
  std::unique_ptr<Segmenter> segmenter;
  uint64_t generation{0};
  SegmentationResult result;
  bool busy{false};      // (m) holds an item from Submit until its Done returned
  bool working{false};   // (m) its Work is to run or running
  bool finished{false};  // (m) Work returned, Done pending
  uint64_t item{0};      // (m)
  std::string error;     // written by the lane before `finished`, read by Done
  bool failed{false};
};

}  // namespace

struct FrameRunner::Impl {
  Impl(const SegmenterParams& seg, const FrameRunnerParams& p, Work w, Done d)
      : params((p.ValidateOrThrow(), p)),
        segmenter_params((seg.ValidateOrThrow(), seg)),
        work(std::move(w)),
        done(std::move(d)),
        pool(p.threads == 1 ? nullptr : std::make_unique<core::ThreadPool>(p.threads)),
        lanes(static_cast<size_t>(p.pipeline_depth)),
        ticket_lane(static_cast<size_t>(p.pipeline_depth), 0) {}

  const FrameRunnerParams params;
  SegmenterParams segmenter_params;  // (m) the latest params
  uint64_t generation{0};            // (m) bumped by UpdateParams
  Work work;
  Done done;
  std::unique_ptr<core::ThreadPool> pool;
  std::vector<LaneState> lanes;

  mutable std::mutex mutex;
  std::condition_variable cv;
  uint64_t submitted{0};                  // (m) tickets handed out
  uint64_t completed{0};                  // (m) tickets whose Done returned
  std::vector<size_t> ticket_lane;        // (m) lane of ticket t at t % lanes
  bool completing{false};                 // (m) a lane is running Done calls
  bool closed{false};                     // (m)
  bool exiting{false};                    // (m) lanes leave when idle
  std::vector<uint64_t> finished_inputs;  // (m)
  std::string done_error;                 // (m)

  Lane View(size_t i) {
    return Lane{static_cast<int>(i), lanes[i].segmenter.get(), &lanes[i].result};
  }

  void LaneLoop(size_t i) {
    char name[16];
    std::snprintf(name, sizeof(name), "cs-lane%zu", i);
    pthread_setname_np(pthread_self(), name);
    LaneState& lane = lanes[i];
    std::unique_lock<std::mutex> lock(mutex);
    for (;;) {
      cv.wait(lock, [&] { return lane.working || exiting; });
      if (!lane.working) return;
      const uint64_t item = lane.item;
      std::unique_ptr<SegmenterParams> fresh;
      if (lane.generation != generation) {
        fresh = std::make_unique<SegmenterParams>(segmenter_params);
        lane.generation = generation;
      }
      lock.unlock();
      lane.failed = false;
      lane.error.clear();
      try {
        if (fresh) lane.segmenter = std::make_unique<Segmenter>(*fresh, pool.get());
        const core::ThreadPool::ActiveCaller active(pool.get());
        work(View(i), item);
      } catch (const std::exception& e) {
        lane.failed = true;
        lane.error = e.what();
      } catch (...) {
        lane.failed = true;
        lane.error = "unknown exception";
      }
      lock.lock();
      lane.working = false;
      lane.finished = true;
      finished_inputs.push_back(item);
      CompleteInOrder(&lock);
      // A camera's next frame is most of a period away once no lane segments and the frames
      // done are completed: the pool's workers stop spinning, so that the threads the
      // completion woke (the sinks) get a core. (Before the completion, its per-pixel passes
      // would first wake blocked workers.)
      RestIfIdleLocked();
      cv.notify_all();
    }
  }

  // Lets the pool rest when the policy puts latency first and no lane segments (mutex held).
  void RestIfIdleLocked() {
    if (params.policy == DispatchPolicy::kLatencyFirst && pool &&
        std::none_of(lanes.begin(), lanes.end(), [](const LaneState& l) { return l.working; })) {
      pool->Rest();
    }
  }

  // Runs Done for every item that is next in submission order and finished. One lane at a
  // time: a lane finishing while another completes leaves its item to that one.
  void CompleteInOrder(std::unique_lock<std::mutex>* lock) {
    if (completing) return;
    completing = true;
    while (completed < submitted) {
      const size_t l = ticket_lane[completed % ticket_lane.size()];
      LaneState& lane = lanes[l];
      if (!lane.finished) break;
      const uint64_t item = lane.item;
      lock->unlock();
      try {
        done(View(l), item, lane.failed ? &lane.error : nullptr);
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> g(mutex);
        if (done_error.empty()) done_error = e.what();
      } catch (...) {
        std::lock_guard<std::mutex> g(mutex);
        if (done_error.empty()) done_error = "unknown exception";
      }
      lock->lock();
      lane.finished = false;
      lane.busy = false;
      ++completed;
      cv.notify_all();
    }
    completing = false;
  }
};

FrameRunner::FrameRunner(const SegmenterParams& segmenter, const FrameRunnerParams& params,
                         Work work, Done done)
    : impl_(std::make_unique<Impl>(segmenter, params, std::move(work), std::move(done))) {
  Impl& m = *impl_;
  for (size_t i = 0; i < m.lanes.size(); ++i) {
    m.lanes[i].segmenter = std::make_unique<Segmenter>(m.segmenter_params, m.pool.get());
  }
  for (size_t i = 0; i < m.lanes.size(); ++i) {
    m.lanes[i].thread = std::thread([&m, i] { m.LaneLoop(i); });
  }
}

FrameRunner::~FrameRunner() {
  Impl& m = *impl_;
  {
    std::unique_lock<std::mutex> lock(m.mutex);
    m.closed = true;
    m.cv.wait(lock, [&] { return m.completed == m.submitted; });
    m.exiting = true;
  }
  m.cv.notify_all();
  for (LaneState& lane : m.lanes) {
    if (lane.thread.joinable()) lane.thread.join();
  }
}

int FrameRunner::num_lanes() const { return static_cast<int>(impl_->lanes.size()); }

core::ThreadPool* FrameRunner::pool() { return impl_->pool.get(); }

bool FrameRunner::Submit(uint64_t item, const std::function<size_t()>& backlog) {
  Impl& m = *impl_;
  std::unique_lock<std::mutex> lock(m.mutex);
  size_t k = m.lanes.size();
  for (;;) {
    if (m.closed) return false;
    k = m.lanes.size();
    bool segmenting = false;
    for (size_t l = m.lanes.size(); l-- > 0;) {
      if (!m.lanes[l].busy) k = l;
      segmenting = segmenting || m.lanes[l].working;
    }
    const bool have_lane = k < m.lanes.size();
    if (have_lane && (m.params.policy == DispatchPolicy::kThroughput || !segmenting ||
                      (backlog && backlog() > 0))) {
      break;
    }
    // Arrivals behind this item are not signalled: poll while it is held back.
    m.cv.wait_for(lock, std::chrono::milliseconds(have_lane ? 1 : 100));
  }
  LaneState& lane = m.lanes[k];
  lane.busy = true;
  lane.working = true;
  lane.item = item;
  m.ticket_lane[m.submitted % m.ticket_lane.size()] = k;
  ++m.submitted;
  lock.unlock();
  m.cv.notify_all();
  return true;
}

void FrameRunner::TakeFinishedInputs(std::vector<uint64_t>* items) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  items->insert(items->end(), impl_->finished_inputs.begin(), impl_->finished_inputs.end());
  impl_->finished_inputs.clear();
}

void FrameRunner::Drain() {
  std::unique_lock<std::mutex> lock(impl_->mutex);
  impl_->cv.wait(lock, [&] { return impl_->completed == impl_->submitted; });
}

void FrameRunner::Close() {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->closed = true;
  }
  impl_->cv.notify_all();
}

void FrameRunner::UpdateParams(const SegmenterParams& params) {
  params.ValidateOrThrow();
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->segmenter_params = params;
  ++impl_->generation;
}

void FrameRunner::ForEachLane(const std::function<void(const Lane&)>& fn) {
  Drain();
  for (size_t i = 0; i < impl_->lanes.size(); ++i) fn(impl_->View(i));
}

void FrameRunner::RestIfIdle() {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->RestIfIdleLocked();
}

uint64_t FrameRunner::completed() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->completed;
}

std::string FrameRunner::done_error() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->done_error;
}

}  // namespace clutterseg::pipeline
