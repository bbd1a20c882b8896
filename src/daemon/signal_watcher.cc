#include "clutterseg/daemon/signal_watcher.h"

#include <poll.h>
#include <pthread.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#include <sys/eventfd.h>
#include <sys/signalfd.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/daemon/log.h"

namespace clutterseg::daemon {

sigset_t BlockDaemonSignals() {
  sigset_t mask;
  sigemptyset(&mask);
  sigaddset(&mask, SIGINT);
  sigaddset(&mask, SIGTERM);
  sigaddset(&mask, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &mask, nullptr);
  return mask;
}

SignalWatcher::SignalWatcher(const sigset_t& mask, std::chrono::milliseconds startup_limit)
    : startup_deadline_(std::chrono::steady_clock::now() + startup_limit),
      step_exit_code_(kExitFailure) {
  signal_fd_ = signalfd(-1, &mask, SFD_CLOEXEC);
  wake_fd_ = eventfd(0, EFD_CLOEXEC);
  if (signal_fd_ < 0 || wake_fd_ < 0) {
    throw std::runtime_error(std::string("cannot watch signals: ") + std::strerror(errno));
  }
  thread_ = std::thread([this] { Loop(); });
}

SignalWatcher::~SignalWatcher() {
  const uint64_t one = 1;
  if (write(wake_fd_, &one, sizeof(one)) < 0) {
    // The thread still ends on its poll timeout.
  }
  if (thread_.joinable()) thread_.join();
  close(wake_fd_);
  close(signal_fd_);
}

void SignalWatcher::Attach(std::function<void()> on_stop, std::function<void()> on_reload) {
  std::lock_guard<std::mutex> lock(mutex_);
  on_stop_ = std::move(on_stop);
  on_reload_ = std::move(on_reload);
  phase_ = Phase::kRunning;
}

void SignalWatcher::Step(const std::string& what, int exit_code) {
  std::lock_guard<std::mutex> lock(mutex_);
  step_ = what;
  step_exit_code_ = exit_code;
}

void SignalWatcher::Detach() {
  std::lock_guard<std::mutex> lock(mutex_);
  phase_ = Phase::kClosing;
  on_stop_ = nullptr;
  on_reload_ = nullptr;
}

std::chrono::steady_clock::time_point SignalWatcher::stop_time() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stop_time_;
}

void SignalWatcher::Loop() {
  pthread_setname_np(pthread_self(), "cs-signals");
  for (;;) {
    pollfd fds[2] = {{signal_fd_, POLLIN, 0}, {wake_fd_, POLLIN, 0}};
    if (poll(fds, 2, 200) < 0) continue;
    if (fds[1].revents & POLLIN) return;
    if (!(fds[0].revents & POLLIN)) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (phase_ == Phase::kStarting && std::chrono::steady_clock::now() > startup_deadline_) {
        Log(LogLevel::kError,
            "start-up did not finish in time: " + step_ + " does not return; exiting");
        std::_Exit(step_exit_code_);
      }
      continue;
    }
    signalfd_siginfo info{};
    if (read(signal_fd_, &info, sizeof(info)) != static_cast<ssize_t>(sizeof(info))) continue;
    const int sig = static_cast<int>(info.ssi_signo);
    const std::string name = strsignal(sig);
    std::unique_lock<std::mutex> lock(mutex_);
    if (sig == SIGHUP) {
      if (phase_ == Phase::kRunning && on_reload_) {
        const auto reload = on_reload_;
        lock.unlock();
        reload();
      } else {
        Log(LogLevel::kWarn, name + ": not running yet (or closing), nothing to reload");
      }
      continue;
    }
    switch (phase_) {
      case Phase::kStarting:
        Log(LogLevel::kInfo, name + " during start-up: exiting (nothing was published)");
        std::_Exit(kExitOk);
      case Phase::kRunning:
        if (!stop_requested_.exchange(true)) {
          stop_time_ = std::chrono::steady_clock::now();
          const auto stop = on_stop_;
          lock.unlock();
          Log(LogLevel::kInfo, name + ": stopping");
          if (stop) stop();
        } else {
          Log(LogLevel::kError, name + " again: exiting at once");
          std::_Exit(kExitFailure);
        }
        break;
      case Phase::kClosing:
        break;  // the log is being closed: let it finish
    }
  }
}

}  // namespace clutterseg::daemon
