#pragma once

#include <signal.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace clutterseg::daemon {

/// Takes SIGINT, SIGTERM and SIGHUP through a signalfd on a thread of its own from the first
/// line of main(), so that a signal is honoured at every moment, start-up included (an LCM
/// handshake that never completes, a device that takes long to open):
///
///  - before Attach() (start-up: nothing is published yet) SIGINT / SIGTERM end the process
///    at once with exit code 0 and a message; SIGHUP is reported and ignored;
///  - attached (running): the first SIGINT / SIGTERM calls `on_stop` (an orderly stop), a
///    second one ends the process at once (exit code 1); SIGHUP calls `on_reload`;
///  - after Detach() (closing the log and the drivers): signals are ignored.
///
/// Start-up has a time limit as well: a step that blocks (an LCM provider waiting for a hub
/// that never answers, a device that never opens) ends the process after `startup_limit`
/// with the exit code and name of the step announced by Step().
///
/// The mask must have been blocked in every thread before any thread was created (the
/// daemon blocks it from a constructor that runs before main). The callbacks run on the
/// watcher's thread and must not throw. Thread-safety: all methods from the owning thread;
/// stop_requested() from any thread.
class SignalWatcher {
 public:
  SignalWatcher(const SignalWatcher&) = delete;
  SignalWatcher& operator=(const SignalWatcher&) = delete;

  /// @throws std::runtime_error when the signalfd cannot be created.
  SignalWatcher(const sigset_t& mask, std::chrono::milliseconds startup_limit);
  ~SignalWatcher();

  /// Names the start-up step now running ("opening LCM URL ...") and the exit code should it
  /// not finish within the start-up limit.
  void Step(const std::string& what, int exit_code);

  void Attach(std::function<void()> on_stop, std::function<void()> on_reload);
  void Detach();
  bool stop_requested() const { return stop_requested_.load(); }
  /// When the first stop signal arrived (valid once stop_requested()).
  std::chrono::steady_clock::time_point stop_time() const;

 private:
  enum class Phase { kStarting, kRunning, kClosing };
  void Loop();

  int signal_fd_{-1};
  int wake_fd_{-1};
  std::thread thread_;
  mutable std::mutex mutex_;  // guards phase_, the callbacks and stop_time_
  Phase phase_{Phase::kStarting};
  std::function<void()> on_stop_;
  std::function<void()> on_reload_;
  std::chrono::steady_clock::time_point stop_time_;
  std::chrono::steady_clock::time_point startup_deadline_;
  std::string step_{"starting"};
  int step_exit_code_{1};
  std::atomic<bool> stop_requested_{false};
};

/// Blocks SIGINT, SIGTERM and SIGHUP in the calling thread (threads created later inherit the
/// mask) and returns that set, for the SignalWatcher.
sigset_t BlockDaemonSignals();

}  // namespace clutterseg::daemon
