#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

#include <sys/types.h>

#include "clutterseg/core/types.h"
#include "clutterseg/daemon/sink_queue.h"
#include "clutterseg/pipeline/overlay.h"

namespace clutterseg::daemon {

/// Overlay PNG output. YAML section `output`.
struct OverlayWriterParams {
  std::string png_dir;    ///< when non-empty, write a label overlay PNG per frame here
  int queue_capacity{4};  ///< frames waiting for the disk before the oldest is dropped

  bool enabled() const { return !png_dir.empty(); }
  /// @throws std::invalid_argument naming the key (`output.<field>`) and value.
  void ValidateOrThrow() const;
};

/// One frame for the overlay writer: its labels, the image to draw them on (the frame's
/// colour image as it is, or its depth shaded grey) and its objects (id, track id, image box)
/// for the boxes, tags and legend.
struct OverlayFrame {
  uint64_t sequence{0};
  core::LabelImage labels;
  core::ColorImage base;
  std::vector<pipeline::OverlayObject> objects;
};

/// The overlay sink: renders each frame's labels over its image, with each object's box, id
/// and track id and a legend (pipeline::RenderOverlay), and writes
/// `<png_dir>/frame_<sequence, 6 digits>.png` on its own thread, behind a bounded
/// drop-oldest queue, so a slow or full disk costs overlays (counted), never segmentation or
/// publishing. A failed write is counted and logged, and the writer goes on.
///
/// Thread-safety: Start and Finish from the owning thread; Offer from one producer thread;
/// the counters from any thread.
class OverlayWriter {
 public:
  OverlayWriter(const OverlayWriter&) = delete;
  OverlayWriter& operator=(const OverlayWriter&) = delete;

  /// @throws std::invalid_argument for bad params.
  explicit OverlayWriter(const OverlayWriterParams& params);
  ~OverlayWriter();

  /// Creates the directory and starts the thread. @throws std::invalid_argument naming
  /// output.png_dir when the directory cannot be created (a configuration error).
  void Start();
  /// Queues a frame (swapped in; `*frame` gets reusable buffers back). When the queue is
  /// full it waits up to `wait_for_room` (none by default: it never blocks) before the
  /// oldest waiting frame is dropped; see SinkQueue::Push.
  void Offer(OverlayFrame* frame,
             std::chrono::milliseconds wait_for_room = std::chrono::milliseconds(0));
  /// Writes what waits, then stops the thread. With `drop_waiting` (a stop signal) the
  /// waiting frames, and the one taken unless its PNG is being written, are dropped and
  /// counted instead: the writer's lowest priority must not hold the exit back.
  void Finish(bool drop_waiting = false);

  uint64_t written() const { return written_.load(); }
  uint64_t failures() const { return failures_.load(); }
  /// Frames dropped: in front of a disk that fell behind, or by a stop (Finish(true)).
  uint64_t dropped() const { return queue_.dropped() + abandoned_.load(); }
  std::string last_error() const;

 private:
  void Loop();

  const OverlayWriterParams params_;
  SinkQueue<OverlayFrame> queue_;
  std::thread thread_;
  std::atomic<uint64_t> written_{0};
  std::atomic<uint64_t> failures_{0};
  std::atomic<pid_t> tid_{0};           // the writer thread, once it runs
  std::atomic<bool> abandon_{false};    // Finish(true): drop instead of writing
  std::atomic<uint64_t> abandoned_{0};  // frames taken, then dropped by a stop
  mutable std::mutex error_mutex_;
  std::string last_error_;
};

}  // namespace clutterseg::daemon
