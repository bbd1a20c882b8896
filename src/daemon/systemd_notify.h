#pragma once

#include <chrono>
#include <string>

namespace clutterseg::daemon {

/// The daemon's side of systemd's notification protocol (Type=notify units, sd_notify(3)):
/// readiness, a status text, and the watchdog. Every call is a no-op when the process was
/// not started by systemd with a notification socket ($NOTIFY_SOCKET unset).
///
/// Thread-safety: any thread.
class SystemdNotifier {
 public:
  SystemdNotifier();

  /// True when systemd listens ($NOTIFY_SOCKET is set).
  bool active() const { return active_; }
  /// The watchdog period the unit asks for (WatchdogSec=), zero when none: keep-alives must
  /// come at least this often; Watchdog() should run about twice as often.
  std::chrono::microseconds watchdog_period() const { return watchdog_; }

  /// READY=1 with a status text: the daemon publishes.
  void Ready(const std::string& status);
  /// STATUS=<text> (what `systemctl status` shows).
  void Status(const std::string& status);
  /// WATCHDOG=1: the daemon is alive and making progress.
  void Watchdog();
  /// STOPPING=1 with a status text.
  void Stopping(const std::string& status);

 private:
  void Send(const std::string& message);

  bool active_{false};
  std::chrono::microseconds watchdog_{0};
};

}  // namespace clutterseg::daemon
