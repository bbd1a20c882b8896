#include "clutterseg/daemon/instance_watch.h"

#include <pthread.h>
#include <unistd.h>

#include <random>

#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/status_t.hpp"

namespace clutterseg::daemon {

const ProcessIdentity& ThisProcess() {
  static const ProcessIdentity identity = [] {
    ProcessIdentity id;
    std::random_device entropy;
    std::mt19937_64 draw((uint64_t{entropy()} << 32) ^ entropy());
    id.instance_id = static_cast<int64_t>(draw() >> 1);  // non-negative
    char host[256] = {};
    if (gethostname(host, sizeof(host) - 1) == 0) id.hostname = host;
    id.pid = static_cast<int32_t>(getpid());
    return id;
  }();
  return identity;
}

InstanceWatch::InstanceWatch(LcmBus* bus, const std::string& status_channel,
                             std::string camera_name)
    : bus_(bus), channel_(status_channel), camera_name_(std::move(camera_name)) {
  bus_->Subscribe<clutterseg::status_t>(channel_, [this](const clutterseg::status_t& s) {
    if (s.instance_id == ThisProcess().instance_id || s.camera_name != camera_name_) return;
    const std::string who = "another clutterseg (pid " + std::to_string(s.pid) + " on " +
                            (s.hostname.empty() ? std::string("an unknown host") : s.hostname) +
                            ", version " + s.version + ", source " + s.source +
                            ") already publishes camera '" + camera_name_ + "' on " + channel_ +
                            " of this bus";
    std::lock_guard<std::mutex> lock(mutex_);
    if (conflict_.empty()) conflict_ = who;
    cv_.notify_all();
  });
  thread_ = std::thread([this] { Loop(); });
}

InstanceWatch::~InstanceWatch() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void InstanceWatch::Loop() {
  pthread_setname_np(pthread_self(), "cs-instances");
  while (!stop_.load()) {
    try {
      if (bus_->Handle(100) < 0) {
        // An LCM error: wait a little rather than spin.
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    } catch (const std::exception& e) {
      Log(LogLevel::kWarn, std::string("instance watch: ") + e.what());
    }
    std::lock_guard<std::mutex> lock(mutex_);
    if (!conflict_.empty() && !logged_) {
      logged_ = true;
      Log(LogLevel::kError, conflict_ +
                                "; subscribers cannot tell the two apart: give each "
                                "daemon its own camera_name");
    }
  }
}

std::string InstanceWatch::WaitForConflict(std::chrono::steady_clock::time_point until) {
  std::unique_lock<std::mutex> lock(mutex_);
  cv_.wait_until(lock, until, [this] { return !conflict_.empty(); });
  // A conflict now is the caller's to report; one seen later, the watch logs.
  logged_ = !conflict_.empty();
  return conflict_;
}

}  // namespace clutterseg::daemon
