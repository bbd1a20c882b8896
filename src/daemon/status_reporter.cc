#include "clutterseg/daemon/status_reporter.h"

#include <pthread.h>

#include <cstdio>

#include "clutterseg/core/param_check.h"
#include "clutterseg/daemon/instance_watch.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/version.h"

namespace clutterseg::daemon {
namespace {

using Clock = std::chrono::steady_clock;

int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

void StatusReporterParams::ValidateOrThrow() const {
  core::ParamCheck("status").InRange("period_s", period_s, 0.05, 3600.0, "s");
}

StatusReporter::StatusReporter(const StatusReporterParams& params, std::string camera_name,
                               std::string source, std::function<StatusCounters()> counters,
                               std::function<void(const clutterseg::status_t&)> publish)
    : params_((params.ValidateOrThrow(), params)),
      camera_name_(std::move(camera_name)),
      source_(std::move(source)),
      counters_(std::move(counters)),
      publish_(std::move(publish)) {}

StatusReporter::~StatusReporter() {
  {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void StatusReporter::Start() {
  thread_ = std::thread([this] { Loop(); });
}

void StatusReporter::Record(double segment_ms, double queue_ms, double capture_to_publish_ms,
                            const clutterseg::stage_times_t& stages) {
  std::lock_guard<std::mutex> lock(mutex_);
  segment_.Add(segment_ms);
  queue_wait_.Add(queue_ms);
  capture_to_publish_.Add(capture_to_publish_ms);
  run_segment_.Add(segment_ms);
  run_capture_to_publish_.Add(capture_to_publish_ms);
  const size_t n = std::min(stages_.size(), static_cast<size_t>(std::max(stages.num_stages, 0)));
  for (size_t i = 0; i < n && i < stages.stage_ms.size(); ++i) stages_[i].Add(stages.stage_ms[i]);
}

void StatusReporter::Finish() {
  {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  Report();  // the final state: end of stream or error, final counters
}

std::string StatusReporter::last_line() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_line_;
}

RunLatency StatusReporter::run_latency() const {
  std::lock_guard<std::mutex> lock(mutex_);
  RunLatency r;
  r.frames = run_capture_to_publish_.count();
  r.segment_p50_ms = run_segment_.Percentile(0.50);
  r.segment_p99_ms = run_segment_.Percentile(0.99);
  r.capture_to_publish_p50_ms = run_capture_to_publish_.Percentile(0.50);
  r.capture_to_publish_p99_ms = run_capture_to_publish_.Percentile(0.99);
  r.capture_to_publish_max_ms = run_capture_to_publish_.max_ms();
  return r;
}

void StatusReporter::Loop() {
  pthread_setname_np(pthread_self(), "cs-status");
  const auto period = std::chrono::microseconds(static_cast<int64_t>(params_.period_s * 1e6));
  auto next = Clock::now() + period;
  std::unique_lock<std::mutex> lock(stop_mutex_);
  for (;;) {
    if (stop_cv_.wait_until(lock, next, [&] { return stop_; })) return;
    lock.unlock();
    try {
      Report();
    } catch (const std::exception& e) {
      Log(LogLevel::kError, std::string("status report failed: ") + e.what());
    }
    lock.lock();
    next = std::max(next + period, Clock::now());
  }
}

void StatusReporter::Report() {
  const StatusCounters c = counters_();
  std::lock_guard<std::mutex> lock(mutex_);
  const auto now = Clock::now();
  const double period_s = std::chrono::duration<double>(now - last_report_).count();
  last_report_ = now;
  const double fps =
      period_s > 0 ? static_cast<double>(c.frames_published - last_published_) / period_s : 0.0;
  last_published_ = c.frames_published;
  const LatencySummary seg = segment_.TakeSummary();
  const LatencySummary qw = queue_wait_.TakeSummary();
  const LatencySummary c2p = capture_to_publish_.TakeSummary();

  clutterseg::status_t& s = status_;
  s.utime = WallMicros();
  s.camera_name = camera_name_;
  s.source = source_;
  s.version = kVersion;
  s.instance_id = ThisProcess().instance_id;
  s.hostname = ThisProcess().hostname;
  s.pid = ThisProcess().pid;
  s.fps = static_cast<float>(fps);
  s.uptime_s = static_cast<float>(std::chrono::duration<double>(now - start_).count());
  s.segment_p50_ms = static_cast<float>(seg.p50_ms);
  s.segment_p99_ms = static_cast<float>(seg.p99_ms);
  s.queue_p50_ms = static_cast<float>(qw.p50_ms);
  s.queue_p99_ms = static_cast<float>(qw.p99_ms);
  s.capture_to_publish_p50_ms = static_cast<float>(c2p.p50_ms);
  s.capture_to_publish_p99_ms = static_cast<float>(c2p.p99_ms);
  s.num_stages = static_cast<int32_t>(pipeline::kNumStages);
  s.stage_names.resize(pipeline::kNumStages);
  s.stage_p50_ms.resize(pipeline::kNumStages);
  s.stage_p99_ms.resize(pipeline::kNumStages);
  for (size_t i = 0; i < pipeline::kNumStages; ++i) {
    const LatencySummary st = stages_[i].TakeSummary();
    s.stage_names[i] = std::string(pipeline::StageTable()[i].name);
    s.stage_p50_ms[i] = static_cast<float>(st.p50_ms);
    s.stage_p99_ms[i] = static_cast<float>(st.p99_ms);
  }
  s.queue_depth = c.queue_depth;
  s.queue_capacity = c.queue_capacity;
  s.frames_captured = static_cast<int64_t>(c.frames_captured);
  s.frames_processed = static_cast<int64_t>(c.frames_processed);
  s.frames_dropped = static_cast<int64_t>(c.frames_dropped);
  s.frames_published = static_cast<int64_t>(c.frames_published);
  s.frames_discarded = static_cast<int64_t>(c.frames_discarded);
  s.frames_publish_dropped = static_cast<int64_t>(c.frames_publish_dropped);
  s.frames_not_delivered = static_cast<int64_t>(c.frames_not_delivered);
  s.frames_expected = c.frames_expected;
  s.frames_capped = static_cast<int64_t>(c.frames_capped);
  s.overlays_written = static_cast<int64_t>(c.overlays_written);
  s.overlays_dropped = static_cast<int64_t>(c.overlays_dropped);
  s.overlay_failures = static_cast<int64_t>(c.overlay_failures);
  s.publish_failures = static_cast<int64_t>(c.publish_failures);
  s.last_num_objects = c.last_num_objects;
  s.device_state = static_cast<int8_t>(c.device_state);
  s.device_state_name = ToString(c.device_state);
  s.reconnect_attempts = static_cast<int32_t>(c.reconnect_attempts);
  s.last_error = c.last_error;
  publish_(s);

  char line[512];
  std::snprintf(line, sizeof(line),
                "%5.1f fps | segment p50 %6.1f p99 %6.1f ms | capture->publish p50 %6.1f p99 "
                "%6.1f ms | objects %d | queue %d/%d | dropped %lld | published %llu | %s%s",
                fps, seg.p50_ms, seg.p99_ms, c2p.p50_ms, c2p.p99_ms, s.last_num_objects,
                s.queue_depth, s.queue_capacity, static_cast<long long>(s.frames_dropped),
                static_cast<unsigned long long>(c.frames_published), s.device_state_name.c_str(),
                s.publish_failures > 0
                    ? (" | publish failures " + std::to_string(s.publish_failures)).c_str()
                    : "");
  LogStatusLine(line);
  last_line_ = line;
}

}  // namespace clutterseg::daemon
