#pragma once

#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "clutterseg/daemon/capture.h"
#include "clutterseg/daemon/latency_stats.h"
#include "clutterseg/pipeline/stage_times.h"
#include "clutterseg/stage_times_t.hpp"
#include "clutterseg/status_t.hpp"

namespace clutterseg::daemon {

/// The status report's period. YAML section `status`.
struct StatusReporterParams {
  double period_s{1.0};  ///< status_t and stderr status line period, seconds

  /// @throws std::invalid_argument naming the key (`status.<field>`) and value.
  void ValidateOrThrow() const;
};

/// The daemon's counters at one moment, for a status report.
struct StatusCounters {
  uint64_t frames_captured{0};
  uint64_t frames_processed{0};
  uint64_t frames_published{0};        ///< objects_t accepted by the transport
  uint64_t frames_dropped{0};          ///< by the frame queue (oldest first)
  uint64_t frames_discarded{0};        ///< waiting frames not segmented because of a stop
  uint64_t frames_publish_dropped{0};  ///< in front of a transport that fell behind
  uint64_t frames_not_delivered{0};    ///< the source could not deliver them
  int64_t frames_expected{-1};         ///< frames the recording holds, -1 when unknown
  uint64_t frames_capped{0};           ///< reached the segmenter's caps
  uint64_t overlays_written{0};
  uint64_t overlays_dropped{0};
  uint64_t overlay_failures{0};
  uint64_t publish_failures{0};
  uint64_t reconnect_attempts{0};
  int32_t queue_depth{0};
  int32_t queue_capacity{0};
  int32_t last_num_objects{0};
  DeviceState device_state{DeviceState::kStarting};
  std::string last_error;
};

/// Latency percentiles of a whole run, milliseconds (LatencyHistogram resolution).
struct RunLatency {
  uint64_t frames{0};
  double segment_p50_ms{0}, segment_p99_ms{0};
  double capture_to_publish_p50_ms{0}, capture_to_publish_p99_ms{0}, capture_to_publish_max_ms{0};
};

/// The status sink: every period (and once at the end) builds a status_t from the latencies
/// recorded since the last report and the counters of the moment, hands it to `publish`, and
/// prints the status line on stderr. Keeps whole-run latency histograms for the end-of-run
/// summary.
///
/// Thread-safety: Start and Finish from the owning thread; Record from one thread (the
/// publisher's); run_latency() from any thread.
class StatusReporter {
 public:
  StatusReporter(const StatusReporter&) = delete;
  StatusReporter& operator=(const StatusReporter&) = delete;

  /// `counters` and `publish` are called on the reporter's thread (and by Finish).
  StatusReporter(const StatusReporterParams& params, std::string camera_name, std::string source,
                 std::function<StatusCounters()> counters,
                 std::function<void(const clutterseg::status_t&)> publish);
  ~StatusReporter();

  void Start();
  /// One published frame: its latencies, milliseconds, and stage times.
  void Record(double segment_ms, double queue_ms, double capture_to_publish_ms,
              const clutterseg::stage_times_t& stages);
  /// Stops the periodic reports and sends the last one.
  void Finish();
  RunLatency run_latency() const;
  /// The latest status line (for systemd's STATUS=), empty before the first report.
  std::string last_line() const;

 private:
  void Loop();
  void Report();

  const StatusReporterParams params_;
  const std::string camera_name_;
  const std::string source_;
  const std::function<StatusCounters()> counters_;
  const std::function<void(const clutterseg::status_t&)> publish_;
  const std::chrono::steady_clock::time_point start_{std::chrono::steady_clock::now()};
  std::thread thread_;
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  bool stop_{false};

  mutable std::mutex mutex_;  // guards everything below
  LatencyWindow segment_, queue_wait_, capture_to_publish_;
  std::array<LatencyWindow, pipeline::kNumStages> stages_;
  LatencyHistogram run_segment_, run_capture_to_publish_;
  uint64_t last_published_{0};
  std::chrono::steady_clock::time_point last_report_{start_};
  clutterseg::status_t status_;
  std::string last_line_;
};

}  // namespace clutterseg::daemon
