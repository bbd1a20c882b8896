#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace clutterseg::daemon {

class LcmBus;

/// Who this process is on the bus, as its status_t says: a random id drawn once per process,
/// the host name and the process id. Thread-safety: any thread (initialised on first use).
struct ProcessIdentity {
  int64_t instance_id{0};
  std::string hostname;
  int32_t pid{0};
};
const ProcessIdentity& ThisProcess();

/// Watches the status channel of a multicast bus (udpm, mpudpm) for another daemon that
/// publishes the same camera_name: its objects_t would interleave with ours on the same
/// channels and a subscriber could not tell the two apart. The daemon waits one status
/// period (plus a margin) before it publishes; a conflict then is a configuration error.
/// Afterwards a conflict is logged once (the other daemon did not check).
///
/// The watch handles messages on `bus` on a thread of its own: use it only on a bus whose
/// subscribers are all its own (the daemon process's bus). Thread-safety: all methods from
/// the owning thread.
class InstanceWatch {
 public:
  InstanceWatch(const InstanceWatch&) = delete;
  InstanceWatch& operator=(const InstanceWatch&) = delete;

  /// Subscribes to `status_channel` and starts handling.
  /// @throws std::runtime_error when LCM refuses the subscription.
  InstanceWatch(LcmBus* bus, const std::string& status_channel, std::string camera_name);
  ~InstanceWatch();

  /// Waits until `until` or until a conflict is seen; returns its description (empty when
  /// none was seen).
  std::string WaitForConflict(std::chrono::steady_clock::time_point until);

 private:
  void Loop();

  LcmBus* bus_;
  const std::string channel_;
  const std::string camera_name_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;  // guards conflict_
  std::condition_variable cv_;
  std::string conflict_;
  bool logged_{true};  // nothing to log until WaitForConflict() found none
};

}  // namespace clutterseg::daemon
