#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "clutterseg/core/frame_pool.h"
#include "clutterseg/core/frame_source.h"

namespace clutterseg::daemon {

/// How a recording is replayed.
enum class Speed {
  kRealtime,  ///< at the recorded frame rate; late frames are dropped like a live camera's
  kMax,       ///< as fast as processing allows, in lockstep: no frame is dropped
};
const char* ToString(Speed speed);

/// State of the frame source as reported in status_t.device_state.
enum class DeviceState : int8_t {
  kStarting = 0,
  kStreaming = 1,
  kReconnecting = 2,
  kEndOfStream = 3,
  kError = 4,
};
const char* ToString(DeviceState state);

/// Parameters of the capture side: the frame queue and reconnection. Their YAML keys are
/// named in each field's comment.
struct CaptureParams {
  int queue_capacity{2};                ///< processing.queue_capacity: frames waiting (drop-oldest)
  double reconnect_backoff_min_s{0.5};  ///< reconnect.backoff_min_s: first retry delay, seconds
  double reconnect_backoff_max_s{8.0};  ///< reconnect.backoff_max_s: delays double up to this
  Speed speed{Speed::kRealtime};        ///< speed: replay speed of recordings
  bool loop{false};                     ///< loop: restart a recording at its end
  std::string camera_name{"camera"};    ///< camera_name: put in every frame
  /// processing.max_frames: in lockstep, stop reading after this many frames (0 = no limit).
  int64_t max_frames{0};

  /// @throws std::invalid_argument naming the YAML key and value.
  void ValidateOrThrow() const;
};

/// The capture thread: reads frames from a FrameSource into the drop-oldest frame queue.
/// Live sources never wait for processing (the queue drops the oldest frame); recordings in
/// lockstep (Speed::kMax) wait for room, so that every frame is processed; at
/// Speed::kRealtime a recording is paced by its timestamps. A lost device is closed and
/// reopened with exponential backoff; the end of a recording ends capture (or restarts it
/// with `loop`). Closes the queue when it ends, so processing sees the end.
///
/// No exception leaves the thread: a source error or exception is passed to `on_error` (on
/// the capture thread) and ends capture.
///
/// Thread-safety: Start and Join from the owning thread; RequestStop, the counters and
/// device_state() from any thread.
class Capture {
 public:
  Capture(const Capture&) = delete;
  Capture& operator=(const Capture&) = delete;

  /// `source` (already open) and `queue` must outlive the Capture; `on_error` is called at
  /// most once, from the capture thread.
  Capture(const CaptureParams& params, core::FrameSource* source, core::FrameQueue* queue,
          std::function<void(const std::string&)> on_error);
  ~Capture();

  void Start();
  /// Stops reading (a blocking Read returns soon); returns at once.
  void RequestStop();
  void Join();

  uint64_t captured() const { return captured_.load(); }
  uint64_t reconnect_attempts() const { return reconnects_.load(); }
  DeviceState device_state() const { return static_cast<DeviceState>(state_.load()); }
  /// The last non-fatal problem (a lost device, a failed reconnect), empty when none.
  std::string last_problem() const;

 private:
  // Logs the frames the source skipped since the last call, each once (capture thread).
  void LogSkips();
  void Loop();
  void Reconnect();
  bool SleepUnlessStopped(std::chrono::microseconds d);
  void SetState(DeviceState s) { state_.store(static_cast<int>(s)); }
  void NoteProblem(const std::string& message);

  const CaptureParams params_;
  core::FrameSource* const source_;
  core::FrameQueue* const queue_;
  const std::function<void(const std::string&)> on_error_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  std::atomic<uint64_t> captured_{0};
  std::atomic<uint64_t> reconnects_{0};
  uint64_t skips_logged_{0};  // serial of the last skipped frame logged (capture thread)
  std::chrono::steady_clock::time_point next_skip_check_{};  // when LogSkips looks again
  std::atomic<int> state_{static_cast<int>(DeviceState::kStarting)};
  mutable std::mutex problem_mutex_;
  std::string last_problem_;
};

}  // namespace clutterseg::daemon
