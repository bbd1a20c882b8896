#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/core/frame_source.h"
#include "clutterseg/daemon/capture.h"
#include "clutterseg/daemon/daemon_config.h"
#include "clutterseg/daemon/status_reporter.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::daemon {

class LcmBus;

/// The frame source could not be opened at start-up.
class SourceOpenError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A snapshot of the daemon's counters: those of its status reports (StatusCounters: frames
/// captured, processed, published, dropped and why, overlays, failures, device state...) and
/// the parameter reloads and the source's own account of its frames.
struct DaemonStats : StatusCounters {
  uint64_t param_reloads{0};  ///< segmenter parameter sets applied after start
  /// What the source delivered and could not (frames skipped with their reasons, the frames
  /// a recording holds, empty frames); see core::SourceReport.
  core::SourceReport source;
};

/// The running daemon, a source, a runner and sinks: Capture (FrameSource -> drop-oldest
/// frame queue), a dispatcher handing frames to a pipeline::FrameRunner (`pipeline_depth`
/// lanes segmenting consecutive frames, one Segmenter each, sharing one ThreadPool), whose
/// ordered completion feeds the sinks: LcmPublisher (objects_t / label_image_t in frame
/// order, status_t), OverlayWriter (PNGs) and StatusReporter (status every period, the
/// stderr status line). Each sink that can block has its own bounded queue and drops and
/// counts rather than delaying the frames behind it.
///
/// Live sources never block on processing (the queue drops the oldest frame); sources that
/// are not live (recordings in lockstep) wait for room instead, so every frame is published.
/// A lost device is closed and reopened with exponential backoff. No exception leaves a
/// thread: errors are recorded, reported in status_t and end the run with exit code 1.
///
/// Thread-safety: Open, Start, WaitFor and Join from the owning thread; RequestStop,
/// UpdateSegmenterParams, UpdateTrackerParams, UpdateExtrinsics, stats() and error() from any
/// thread.
class Daemon {
 public:
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;
  Daemon(Daemon&&) = delete;
  Daemon& operator=(Daemon&&) = delete;

  /// `bus` must outlive the daemon and is used only by its publisher thread once started.
  /// @throws std::invalid_argument when `config` is invalid.
  Daemon(const DaemonConfig& config, std::unique_ptr<core::FrameSource> source, LcmBus* bus);
  /// Requests a stop and joins all threads.
  ~Daemon();

  /// Opens the source on the calling thread (a device or a long recording may take a while);
  /// no thread runs and nothing is published yet. Optional: Start() opens it otherwise.
  /// @throws SourceOpenError when the source cannot be opened.
  void Open();
  /// Opens the source unless Open() did, then starts the threads. A RequestStop() that came
  /// after Open() makes the threads finish at once (with a last status_t).
  /// @throws SourceOpenError when the source cannot be opened; std::invalid_argument naming
  /// output.png_dir when the overlay directory cannot be created (nothing is started then).
  void Start();
  /// Asks for an orderly stop: capture stops, frames being segmented finish and are
  /// published, waiting frames are discarded, overlays waiting for the disk are dropped (both
  /// counted), a last status_t is sent. Returns at once.
  void RequestStop();
  /// Replaces the segmentation parameters; each lane applies them before its next frame.
  /// @throws std::invalid_argument when `params` are invalid (the old ones stay).
  void UpdateSegmenterParams(const pipeline::SegmenterParams& params);
  /// Replaces the tracker's parameters before the next frame it tracks; the tracks are kept.
  /// No effect with tracker.enabled false. @throws std::invalid_argument when invalid.
  void UpdateTrackerParams(const pipeline::TrackerParams& params);
  /// Replaces the camera's pose in its parent frame (camera.extrinsics_file; nullopt = the
  /// camera frame) from the next frame a lane starts; each frame's objects and lost tracks are
  /// published with the pose its lane started with. Returns true when the pose or the frame
  /// changed.
  bool UpdateExtrinsics(std::optional<core::Extrinsics> extrinsics);
  /// Waits until every thread has finished (end of stream, max_frames, stop or error) or
  /// `timeout` passes; returns true when finished.
  bool WaitFor(std::chrono::milliseconds timeout);
  /// Waits for the end and joins the threads.
  void Join();

  /// kExitOk, or kExitRuntimeError after a failure (valid once finished).
  int exit_code() const;
  /// The first error recorded, empty when none.
  std::string error() const;
  DaemonStats stats() const;
  /// Description of the source, e.g. for logs.
  std::string source_description() const;
  /// Latency percentiles over the whole run (valid once finished), for the summary line.
  RunLatency run_latency() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::daemon
