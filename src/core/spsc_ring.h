#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

#include "clutterseg/core/assert.h"

namespace clutterseg::core {
namespace internal {

/// Lets one thread sleep until another thread changes some atomic state, without taking a
/// lock on the signalling side unless the waiter is actually asleep. The waiter's predicate
/// and the signaller's state change must both use seq_cst operations (Dekker pattern with
/// `sleeping_`), so a wakeup cannot be lost.
class SleepGate {
 public:
  /// Waits until `ready()` is true or `timeout` passed; returns the last `ready()`.
  template <typename Pred>
  bool WaitFor(Pred ready, std::chrono::nanoseconds timeout) {
    if (ready()) return true;
    std::unique_lock<std::mutex> lock(mutex_);
    sleeping_.store(true, std::memory_order_seq_cst);
    const bool ok = cv_.wait_for(lock, timeout, ready);
    sleeping_.store(false, std::memory_order_seq_cst);
    return ok;
  }
  /// Wakes the waiter if it sleeps. Call after the seq_cst change that makes `ready()` true.
  void Notify() {
    if (sleeping_.load(std::memory_order_seq_cst)) {
      std::lock_guard<std::mutex> lock(mutex_);
      cv_.notify_all();
    }
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::atomic<bool> sleeping_{false};
};

#ifndef NDEBUG
/// Debug-only detector of two threads in the producer (or consumer) side at once.
class RoleGuard {
 public:
  explicit RoleGuard(std::atomic<bool>* busy) : busy_(busy) {
    CLUTTERSEG_DEMAND(!busy_->exchange(true, std::memory_order_acquire) &&
                      "concurrent use of one side of an SpscRing");
  }
  ~RoleGuard() { busy_->store(false, std::memory_order_release); }
  RoleGuard(const RoleGuard&) = delete;
  RoleGuard& operator=(const RoleGuard&) = delete;

 private:
  std::atomic<bool>* busy_;
};
#endif

inline constexpr size_t kCacheLineBytes = 64;

}  // namespace internal

/// A bounded, lock-free single-producer / single-consumer queue of reusable slots with a
/// drop-oldest policy, for frames travelling from a capture thread to processing.
///
/// The ring owns `capacity + 1 + max_consumer_held` preallocated slots of T; nothing is
/// allocated after construction and slot contents (and their buffers) are reused. The
/// producer fills the slot returned by acquire() and publishes it with push(). When
/// `capacity` frames are already waiting, push() reclaims the OLDEST waiting frame (a CAS on
/// the consumer's read index, so it never races with a concurrent pop), counts it as
/// dropped and reuses its slot for a later acquire(). The consumer takes frames with
/// try_pop() / wait_pop_for(), in push order, and hands each slot back with release(); it may
/// hold at most `max_consumer_held` slots at a time.
///
/// Counters: at any quiescent point pushed() == popped() + dropped() + size().
///
/// Thread-safety: acquire, push, wait_not_full_for and close are producer-thread only;
/// try_pop, wait_pop_for, release and drained are consumer-thread only (a debug build aborts
/// on concurrent use of one side); the counters, size() and closed() may be read from any
/// thread. Only the waits block (on a condition variable, only when the queue is empty or
/// full); every other operation is lock-free.
template <typename T>
class SpscRing {
 public:
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;
  SpscRing(SpscRing&&) = delete;
  SpscRing& operator=(SpscRing&&) = delete;

  /// `capacity` >= 1 frames may wait; the consumer may hold `max_consumer_held` >= 1 popped
  /// slots before releasing them. `init`, when given, is called once on every slot (e.g. to
  /// size image buffers up front).
  explicit SpscRing(size_t capacity, size_t max_consumer_held = 1,
                    const std::function<void(T*)>& init = {})
      : capacity_(capacity),
        max_held_(max_consumer_held),
        num_slots_(capacity + 1 + max_consumer_held),
        slots_(num_slots_),
        ring_(new std::atomic<uint32_t>[capacity]),
        free_(new std::atomic<uint32_t>[num_slots_]) {
    CLUTTERSEG_DEMAND(capacity >= 1 && max_consumer_held >= 1);
    CLUTTERSEG_DEMAND(num_slots_ < std::numeric_limits<uint32_t>::max());
    for (size_t i = 0; i < capacity_; ++i) ring_[i].store(kNoSlot, std::memory_order_relaxed);
    for (size_t i = 0; i < num_slots_; ++i) {
      free_[i].store(static_cast<uint32_t>(i), std::memory_order_relaxed);
      if (init) init(&slots_[i]);
    }
    free_tail_.store(num_slots_, std::memory_order_release);
  }

  // ---- producer side -------------------------------------------------------------------

  /// The slot to fill next (its previous contents are still there, buffers reused). Calling
  /// it again before push() returns the same slot. Never fails. Producer thread only.
  T* acquire() {
#ifndef NDEBUG
    internal::RoleGuard guard(&producer_busy_);
#endif
    if (writing_ == kNoSlot) {
      if (spare_ != kNoSlot) {
        writing_ = spare_;
        spare_ = kNoSlot;
      } else {
        const uint64_t h = free_head_.load(std::memory_order_relaxed);
        const uint64_t t = free_tail_.load(std::memory_order_acquire);
        // Holds by construction: the producer, the ring and the consumer together never
        // hold more than num_slots_ - 1 slots when the producer has none.
        CLUTTERSEG_DEMAND(t != h);
        writing_ = free_[h % num_slots_].load(std::memory_order_relaxed);
        free_head_.store(h + 1, std::memory_order_release);
      }
    }
    return &slots_[writing_];
  }

  /// Publishes the acquired slot. When the queue was full, the oldest waiting frame is
  /// dropped first (and counted); returns true in that case. Producer thread only.
  bool push() {
#ifndef NDEBUG
    internal::RoleGuard guard(&producer_busy_);
#endif
    CLUTTERSEG_DEMAND(writing_ != kNoSlot && "push() without acquire()");
    const uint64_t t = tail_.load(std::memory_order_relaxed);
    uint64_t h = head_.load(std::memory_order_seq_cst);
    bool dropped = false;
    while (t - h >= capacity_) {
      // Full: take the oldest frame away from the consumer. Only the producer writes ring
      // entries and index t = h + capacity is not written yet, so entry h is intact.
      const uint32_t victim = ring_[h % capacity_].load(std::memory_order_relaxed);
      if (head_.compare_exchange_weak(h, h + 1, std::memory_order_seq_cst,
                                      std::memory_order_seq_cst)) {
        spare_ = victim;
        dropped = true;
        dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
        break;
      }
      // The consumer popped it (or a spurious failure): h was reloaded, test again.
    }
    ring_[t % capacity_].store(writing_, std::memory_order_relaxed);
    writing_ = kNoSlot;
    tail_.store(t + 1, std::memory_order_seq_cst);
    pushed_.store(pushed_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    not_empty_.Notify();
    return dropped;
  }

  /// Blocks until fewer than capacity() frames wait (so the next push() drops nothing) or
  /// `timeout` passes; returns true when there is room. For sources read in lockstep
  /// (recordings at full speed) that must not lose frames. Producer thread only.
  bool wait_not_full_for(std::chrono::nanoseconds timeout) {
    return not_full_.WaitFor([this] { return size() < capacity_; }, timeout);
  }

  /// Marks the end of the stream: after the waiting frames are popped, wait_pop_for() returns
  /// null at once and drained() is true. Producer thread only (idempotent).
  void close() {
    closed_.store(true, std::memory_order_seq_cst);
    not_empty_.Notify();
  }

  // ---- consumer side -------------------------------------------------------------------

  /// The oldest waiting frame, or null when none waits. The caller must release() it.
  /// Consumer thread only.
  T* try_pop() {
#ifndef NDEBUG
    internal::RoleGuard guard(&consumer_busy_);
#endif
    CLUTTERSEG_DEMAND(held_ < max_held_ && "more than max_consumer_held slots popped");
    uint64_t h = head_.load(std::memory_order_seq_cst);
    for (;;) {
      const uint64_t t = tail_.load(std::memory_order_seq_cst);
      if (h == t) return nullptr;
      // May race with the producer writing entry h + capacity after dropping h; then the
      // CAS below fails because head has moved, and the value read is discarded.
      const uint32_t idx = ring_[h % capacity_].load(std::memory_order_relaxed);
      if (head_.compare_exchange_weak(h, h + 1, std::memory_order_seq_cst,
                                      std::memory_order_seq_cst)) {
        ++held_;
        popped_.store(popped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
        not_full_.Notify();
        return &slots_[idx];
      }
    }
  }

  /// Like try_pop(), but waits up to `timeout` for a frame. Returns null on timeout or at
  /// once when the queue is closed and empty. Consumer thread only.
  T* wait_pop_for(std::chrono::nanoseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      if (T* slot = try_pop()) return slot;
      if (closed_.load(std::memory_order_seq_cst) && empty()) return nullptr;
      const auto now = std::chrono::steady_clock::now();
      if (now >= deadline) return nullptr;
      not_empty_.WaitFor([this] { return !empty() || closed_.load(std::memory_order_seq_cst); },
                         deadline - now);
    }
  }

  /// Hands a popped slot back for reuse. Consumer thread only.
  void release(T* slot) {
#ifndef NDEBUG
    internal::RoleGuard guard(&consumer_busy_);
#endif
    CLUTTERSEG_DEMAND(slot >= slots_.data() && slot < slots_.data() + num_slots_);
    CLUTTERSEG_DEMAND(held_ > 0);
    const uint64_t t = free_tail_.load(std::memory_order_relaxed);
    free_[t % num_slots_].store(static_cast<uint32_t>(slot - slots_.data()),
                                std::memory_order_relaxed);
    free_tail_.store(t + 1, std::memory_order_release);
    --held_;
  }

  /// True when close() was called and every pushed frame was popped or dropped. Consumer
  /// thread only (any thread gets a possibly stale answer).
  bool drained() const { return closed_.load(std::memory_order_seq_cst) && empty(); }

  // ---- any thread ----------------------------------------------------------------------

  /// Frames waiting now (a snapshot).
  size_t size() const {
    const uint64_t h = head_.load(std::memory_order_seq_cst);
    const uint64_t t = tail_.load(std::memory_order_seq_cst);
    return static_cast<size_t>(t - h);
  }
  bool empty() const { return size() == 0; }
  size_t capacity() const { return capacity_; }
  size_t max_consumer_held() const { return max_held_; }
  bool closed() const { return closed_.load(std::memory_order_seq_cst); }
  /// Frames published by push() since construction.
  uint64_t pushed() const { return pushed_.load(std::memory_order_relaxed); }
  /// Frames handed to the consumer since construction.
  uint64_t popped() const { return popped_.load(std::memory_order_relaxed); }
  /// Frames discarded by push() because the queue was full.
  uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  static constexpr uint32_t kNoSlot = std::numeric_limits<uint32_t>::max();

  const size_t capacity_;
  const size_t max_held_;
  const size_t num_slots_;
  std::vector<T> slots_;
  // ring_[i % capacity_] = slot index of the i-th pushed frame, for head_ <= i < tail_.
  std::unique_ptr<std::atomic<uint32_t>[]> ring_;
  // Free slot indices released by the consumer: free_[i % num_slots_], free_head_ <= i <
  // free_tail_ (a plain SPSC queue in the other direction).
  std::unique_ptr<std::atomic<uint32_t>[]> free_;

  // Consumer's read index; the producer also advances it (CAS) when it drops the oldest.
  alignas(internal::kCacheLineBytes) std::atomic<uint64_t> head_{0};
  std::atomic<uint64_t> popped_{0};
  std::atomic<uint64_t> free_tail_{0};
  size_t held_{0};  // consumer-owned
  // Producer's write index and producer-owned state.
  alignas(internal::kCacheLineBytes) std::atomic<uint64_t> tail_{0};
  std::atomic<uint64_t> pushed_{0};
  std::atomic<uint64_t> dropped_{0};
  std::atomic<uint64_t> free_head_{0};
  uint32_t writing_{kNoSlot};  // slot being filled
  uint32_t spare_{kNoSlot};    // slot reclaimed from a drop, reused by the next acquire()

  alignas(internal::kCacheLineBytes) std::atomic<bool> closed_{false};
  internal::SleepGate not_empty_;  // the consumer sleeps here
  internal::SleepGate not_full_;   // the producer sleeps here
#ifndef NDEBUG
  std::atomic<bool> producer_busy_{false};
  std::atomic<bool> consumer_busy_{false};
#endif
};

}  // namespace clutterseg::core
