#pragma once

#include <string>

namespace clutterseg::daemon {

/// Real-time scheduling of the daemon's threads (key `processing.realtime_priority`).
///
/// Several cameras on one host load its cores with frames that arrive at the same instants.
/// Under the normal time-sharing class every frame in flight gets a slice of the cores, so all
/// of them finish late; under SCHED_FIFO a frame that has a core keeps it until it is done, and
/// the threads that carry frames in and out (capture, dispatch, publisher) preempt the
/// segmentation at once. docs/daemon.md ("Several cameras on one host") gives the
/// measurements that chose it for the multi-camera template unit.
struct RealtimeParams {
  /// 0 = the normal class (the default). 1..98 = SCHED_FIFO: the segmentation lanes and the
  /// pool's workers at this priority, capture, dispatch, the publisher and the status reporter
  /// at one more. The source driver's own threads (see ScopedNormalClass), the overlay writer
  /// (nice 19), the signal thread and the main thread stay in the normal class. Needs
  /// CAP_SYS_NICE or an RLIMIT_RTPRIO of at least priority + 1 (systemd: LimitRTPRIO=); without
  /// them the daemon says so and runs in the normal class.
  int priority{0};

  /// @throws std::invalid_argument naming the key and value.
  void ValidateOrThrow() const;
};

/// Puts the calling thread in SCHED_FIFO at `priority` (1..99), or back in the normal class
/// (SCHED_OTHER, its nice value kept) for 0. Threads it starts afterwards inherit the class and
/// priority. Returns false with `*problem` set (the reason and what permits it) when the kernel
/// refuses; the thread's class is then unchanged.
/// Thread-safety: affects only the calling thread; safe from any thread.
bool SetThreadRealtime(int priority, std::string* problem);

/// True when the calling thread runs in a real-time class (SCHED_FIFO or SCHED_RR).
bool ThreadIsRealtime();

/// Puts the calling thread in the normal class for the scope (when it is in a real-time
/// class) and restores its class and priority at the end. Wraps the calls that open a source:
/// the threads a driver starts inherit the class of the thread that starts them, and a
/// driver's thread that busy-waits (OniFile's player does at the end of a recording) must never
/// run in a real-time class, where it would keep every thread of its priority off that core.
/// Thread-safety: affects only the calling thread.
class ScopedNormalClass {
 public:
  ScopedNormalClass();
  ~ScopedNormalClass();
  ScopedNormalClass(const ScopedNormalClass&) = delete;
  ScopedNormalClass& operator=(const ScopedNormalClass&) = delete;

 private:
  int policy_{0};
  int priority_{0};
  bool restore_{false};
};

}  // namespace clutterseg::daemon
