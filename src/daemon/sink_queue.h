#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <utility>
#include <vector>

namespace clutterseg::daemon {

/// The bounded queue in front of a sink that can block (a network peer, a disk): when
/// `capacity` items are already waiting, Push waits at most its `wait_for_room` (none by
/// default) and then drops the oldest and counts it, so a stalled sink costs frames, never
/// more than that of the producer's time. Items move by swap: Push hands the
/// caller back the buffers of a spent slot and Pop those of the consumer's previous item, so
/// after the first rounds nothing is allocated.
///
/// Thread-safety: Push from one producer thread, Pop from one consumer thread, Close and the
/// counters from any thread.
template <typename T>
class SinkQueue {
 public:
  SinkQueue(const SinkQueue&) = delete;
  SinkQueue& operator=(const SinkQueue&) = delete;

  explicit SinkQueue(size_t capacity) : slots_(capacity > 0 ? capacity : 1) {}

  /// Swaps `*item` into the queue; `*item` is left with reusable buffers. When the queue is
  /// full it first waits up to `wait_for_room` for the consumer to take one (a recording
  /// replayed in lockstep, where a frame must not be lost to a sink that is merely slower
  /// for a moment), then drops the oldest waiting item. Returns false (nothing queued) after
  /// Close().
  bool Push(T* item, std::chrono::milliseconds wait_for_room = std::chrono::milliseconds(0)) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      if (closed_) return false;
      if (count_ == slots_.size() && wait_for_room.count() > 0) {
        not_full_.wait_for(lock, wait_for_room, [&] { return count_ < slots_.size() || closed_; });
        if (closed_) return false;
      }
      if (count_ == slots_.size()) {
        head_ = (head_ + 1) % slots_.size();
        --count_;
        ++dropped_;
      }
      using std::swap;
      swap(slots_[(head_ + count_) % slots_.size()], *item);
      ++count_;
      ++pushed_;
    }
    cv_.notify_one();
    return true;
  }

  /// Waits up to `timeout` for the oldest item and swaps it into `*out`. Returns false on
  /// timeout, or once the queue is closed and empty.
  bool Pop(T* out, std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!cv_.wait_for(lock, timeout, [&] { return count_ > 0 || closed_; })) return false;
    if (count_ == 0) return false;
    using std::swap;
    swap(*out, slots_[head_]);
    head_ = (head_ + 1) % slots_.size();
    --count_;
    lock.unlock();
    not_full_.notify_one();
    return true;
  }

  /// No further Push; Pop returns the items still waiting, then false.
  void Close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    cv_.notify_all();
    not_full_.notify_all();
  }

  /// Close(), and the items still waiting are dropped (counted in dropped()) rather than
  /// handed to Pop: a stop that must not wait for a slow consumer. Returns how many.
  size_t CloseAndDropWaiting() {
    size_t n = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
      n = count_;
      dropped_ += count_;
      head_ = (head_ + count_) % slots_.size();
      count_ = 0;
    }
    cv_.notify_all();
    not_full_.notify_all();
    return n;
  }

  bool closed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return closed_;
  }
  /// True when closed and nothing is waiting.
  bool drained() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return closed_ && count_ == 0;
  }
  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return count_;
  }
  size_t capacity() const { return slots_.size(); }
  uint64_t pushed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return pushed_;
  }
  /// Items dropped because the queue was full.
  uint64_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;        // an item waits, or closed
  std::condition_variable not_full_;  // a slot is free, or closed
  std::vector<T> slots_;
  size_t head_{0};
  size_t count_{0};
  uint64_t pushed_{0};
  uint64_t dropped_{0};
  bool closed_{false};
};

}  // namespace clutterseg::daemon
