// How the daemon process watches a run to its end: systemd keep-alive, the drain's time limits,
// and what it reports when the run is over.
#include "clutterseg/daemon/run_watch.h"

#include <cstdio>
#include <cstdlib>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/daemon/log.h"

namespace clutterseg::daemon {
namespace {

// Whether the daemon makes progress, for systemd's watchdog: frames are published, or it is
// legitimately waiting (reconnecting a lost device, at the end of a recording).
class ProgressWatch {
 public:
  explicit ProgressWatch(std::chrono::microseconds period) : period_(period) {}
  bool Alive(const DaemonStats& s) {
    const auto now = std::chrono::steady_clock::now();
    if (s.frames_published != last_published_ || s.device_state != DeviceState::kStreaming) {
      last_published_ = s.frames_published;
      last_progress_ = now;
    }
    return now - last_progress_ < period_;
  }

 private:
  std::chrono::microseconds period_;
  uint64_t last_published_{~uint64_t{0}};
  std::chrono::steady_clock::time_point last_progress_{std::chrono::steady_clock::now()};
};

// Captured frames that were neither published nor dropped and counted.
uint64_t Unpublished(const DaemonStats& s) {
  const uint64_t accounted = s.frames_published + s.frames_dropped + s.frames_discarded;
  return s.frames_captured > accounted ? s.frames_captured - accounted : 0;
}

// Work done by the sinks, to tell a slow drain from a stuck one.
uint64_t DrainProgress(const DaemonStats& s) {
  return s.frames_processed + s.frames_published + s.publish_failures + s.overlays_written +
         s.overlay_failures;
}

}  // namespace

bool IsSharedBus(const std::string& url) {
  for (const char* scheme : {"udpm://", "mpudpm://"}) {
    if (url.rfind(scheme, 0) == 0) return true;
  }
  return false;
}

bool IsNetworkBus(const std::string& url) {
  return IsSharedBus(url) || url.rfind("tcpq://", 0) == 0;
}

void WaitUntilDone(const SignalWatcher& signals, bool network_transport, SystemdNotifier* notifier,
                   Daemon* daemon) {
  const auto watchdog = notifier->watchdog_period();
  ProgressWatch progress(watchdog > std::chrono::microseconds(0) ? watchdog
                                                                 : std::chrono::seconds(30));
  auto next_keepalive = std::chrono::steady_clock::now();
  bool draining = false;
  uint64_t drain_progress = 0;
  auto last_drain_progress = std::chrono::steady_clock::now();
  while (!daemon->WaitFor(std::chrono::milliseconds(50))) {
    const auto now = std::chrono::steady_clock::now();
    const DaemonStats s = daemon->stats();
    if (!draining && (signals.stop_requested() || s.device_state == DeviceState::kEndOfStream ||
                      s.device_state == DeviceState::kError)) {
      draining = true;
      drain_progress = DrainProgress(s);
      last_drain_progress = now;
      if (signals.stop_requested()) notifier->Stopping("finishing the frames in flight");
    }
    if (draining) {
      if (network_transport && signals.stop_requested() &&
          now - signals.stop_time() > kNetworkStopLimit) {
        Log(LogLevel::kError,
            "stop: the LCM transport did not take the last messages within " +
                std::to_string(kNetworkStopLimit.count()) + " ms of the signal; exiting with " +
                std::to_string(Unpublished(s)) + " captured frames not published");
        std::_Exit(kExitIncomplete);
      }
      if (DrainProgress(s) != drain_progress) {
        drain_progress = DrainProgress(s);
        last_drain_progress = now;
      } else if (now - last_drain_progress > kDrainStallLimit) {
        Log(LogLevel::kError,
            "the pipeline made no progress for " +
                std::to_string(std::chrono::seconds(kDrainStallLimit).count()) +
                " s while finishing (an LCM transport or the disk does not return); exiting "
                "with " +
                std::to_string(Unpublished(s)) + " captured frames not published");
        std::_Exit(kExitIncomplete);
      }
    }
    if (notifier->active() && now >= next_keepalive) {
      next_keepalive = now + std::chrono::milliseconds(500);
      // A pipeline that stopped publishing while frames stream gets no keep-alive: systemd
      // then restarts it (WatchdogSec= of the unit).
      if (watchdog > std::chrono::microseconds(0) && progress.Alive(s)) notifier->Watchdog();
      notifier->Status(std::string(ToString(s.device_state)) + ", " +
                       std::to_string(s.frames_published) + " frames published, " +
                       std::to_string(s.frames_dropped) + " dropped");
    }
  }
}

std::vector<std::string> Undelivered(const DaemonStats& s, const std::string& log_problem) {
  std::vector<std::string> missing;
  auto count = [&](uint64_t n, const char* what) {
    if (n > 0) missing.push_back(std::to_string(n) + " " + what);
  };
  if (s.source.lost_frames()) {
    std::string reasons;
    for (size_t r = 0; r < core::kNumSkipReasons; ++r) {
      const uint64_t n = s.source.skipped[r];
      if (n == 0) continue;
      reasons += std::string(reasons.empty() ? "" : ", ") + std::to_string(n) + " " +
                 core::ToString(static_cast<core::SkipReason>(r));
    }
    missing.push_back(std::to_string(s.source.frames_skipped()) +
                      " frames of the source not delivered (" + reasons + ")");
  }
  count(s.publish_failures, "messages refused by the LCM transport");
  count(s.frames_publish_dropped, "frames dropped in front of a transport that fell behind");
  count(s.overlay_failures, "overlay PNGs not written");
  if (!log_problem.empty()) missing.push_back(log_problem);
  return missing;
}

std::string Summary(const DaemonStats& s, const RunLatency& lat) {
  char latency[200];
  std::snprintf(latency, sizeof(latency),
                "; whole run: capture->publish p50 %.1f p99 %.1f max %.1f ms, segment p50 "
                "%.1f p99 %.1f ms over %llu frames",
                lat.capture_to_publish_p50_ms, lat.capture_to_publish_p99_ms,
                lat.capture_to_publish_max_ms, lat.segment_p50_ms, lat.segment_p99_ms,
                static_cast<unsigned long long>(lat.frames));
  return "done: " + std::to_string(s.frames_captured) + " captured, " +
         std::to_string(s.frames_processed) + " processed, " + std::to_string(s.frames_published) +
         " published, " + std::to_string(s.frames_dropped) + " dropped, " +
         std::to_string(s.publish_failures) + " publish failures" +
         // Frames still waiting when a stop came: captured, never segmented (the count that
         // makes captured = processed + dropped + discarded).
         (s.frames_discarded > 0
              ? ", " + std::to_string(s.frames_discarded) + " discarded at the stop"
              : "") +
         (s.frames_publish_dropped > 0
              ? ", " + std::to_string(s.frames_publish_dropped) + " dropped before the transport"
              : "") +
         (s.overlay_failures + s.overlays_dropped > 0
              ? ", overlays " + std::to_string(s.overlays_written) + " written / " +
                    std::to_string(s.overlays_dropped) + " dropped / " +
                    std::to_string(s.overlay_failures) + " failed"
              : "") +
         latency;
}

}  // namespace clutterseg::daemon
