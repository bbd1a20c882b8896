#pragma once

#include <string>

namespace clutterseg::daemon {

/// Real-time scheduling of the daemon's threads (key `processing.realtime_priority`).
///
/// Several cameras on one host load its cores with frames that arrive at the same instants.
/// Under the normal time-sharing class every frame in flight gets a slice of the cores, so all
/// of them finish late; under SCHED_FIFO a frame that has a core keeps it until it is done, and
/// the threads that carry frames in and out (the camera driver, capture, dispatch, publisher)
/// preempt the segmentation at once. docs/daemon.md ("Several cameras on one host") gives the
/// measurements that chose it for the multi-camera template unit.
struct RealtimeParams {
  /// 0 = the normal class (the default). 1..98 = SCHED_FIFO: the segmentation lanes and the
  /// pool's workers at this priority, the source's driver threads, capture, dispatch, the
  /// publisher and the status reporter at one more. The overlay writer (nice 19), the signal
  /// thread and the main thread stay in the normal class. Needs
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

}  // namespace clutterseg::daemon
