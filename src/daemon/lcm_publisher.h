#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/daemon/sink_queue.h"
#include "clutterseg/depth_image_t.hpp"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"

namespace clutterseg::daemon {

/// Where and what the daemon publishes. YAML section `lcm`.
struct LcmPublisherParams {
  /// LCM provider URL; empty = $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0.
  std::string url;
  std::string objects_channel{"CLUTTERSEG_OBJECTS"};  ///< objects_t channel
  std::string labels_channel{"CLUTTERSEG_LABELS"};    ///< label_image_t channel
  std::string status_channel{"CLUTTERSEG_STATUS"};    ///< status_t channel
  bool publish_labels{true};                          ///< publish a label_image_t per frame
  LabelCompression label_compression{LabelCompression::kRle};
  /// Publish each frame's depth image (depth_image_t, zlib) on depth_channel, so consumers
  /// get geometry without a second camera reader (about 150 kB per 640x480 frame).
  bool publish_depth{false};
  std::string depth_channel{"CLUTTERSEG_DEPTH"};  ///< depth_image_t channel
  /// Per object, up to this many of its points in object_t.samples (0 = none).
  int object_points{0};
  /// On a multicast bus (udpm, mpudpm), refuse to start when another daemon publishes the
  /// same camera_name there (found by listening to status_channel for one status period).
  /// Also, on a transport others on this host can hear (udpm, mpudpm, tcpq), hold a lock
  /// per camera_name in lock_dir for the process's life (InstanceLock).
  bool check_instances{true};
  /// Directory of the per-camera lock files; empty = DefaultLockDir() ($RUNTIME_DIRECTORY,
  /// /run/clutterseg, $XDG_RUNTIME_DIR/clutterseg, /tmp/clutterseg-UID).
  std::string lock_dir;
  /// Frames that may wait for a slow transport (a stalled tcpq peer, a slow disk under a
  /// file:// log) before the oldest is dropped and counted.
  int queue_capacity{4};

  /// @throws std::invalid_argument naming the key (`lcm.<field>`) and value.
  void ValidateOrThrow() const;
};

/// One frame's messages on their way to the bus.
struct FrameMessages {
  clutterseg::objects_t objects;
  clutterseg::label_image_t labels;
  clutterseg::depth_image_t depth;
  bool has_labels{false};
  bool has_depth{false};
  int64_t receive_utime{0};  ///< steady clock, microseconds: when the frame entered the process
  double segment_ms{0.0};    ///< segmentation wall time, for the status report
};

/// The LCM sink: publishes each frame's objects_t (and label_image_t) and the status
/// reports on its own thread, which alone uses the bus. Frames reach it through a bounded
/// drop-oldest queue, so a transport that blocks costs frames (counted) and never delays
/// segmentation or capture. objects_t.capture_to_publish_ms is stamped just before publishing.
///
/// Thread-safety: Start, Flush and Finish from the owning thread; Offer from one producer
/// thread; OfferStatus and the counters from any thread.
class LcmPublisher {
 public:
  LcmPublisher(const LcmPublisher&) = delete;
  LcmPublisher& operator=(const LcmPublisher&) = delete;

  /// Called on the publisher thread after each frame: its messages (capture_to_publish_ms
  /// set) and whether the transport accepted its objects_t.
  using OnPublished = std::function<void(const FrameMessages& frame, bool ok)>;

  /// `bus` must outlive the publisher. @throws std::invalid_argument for bad params.
  LcmPublisher(const LcmPublisherParams& params, LcmBus* bus, OnPublished on_published);
  ~LcmPublisher();

  void Start();
  /// Queues a frame (swapped in; `*frame` gets reusable buffers back). When the queue is
  /// full it waits up to `wait_for_room` (none by default: it never blocks) before the
  /// oldest waiting frame is dropped; see SinkQueue::Push.
  void Offer(FrameMessages* frame,
             std::chrono::milliseconds wait_for_room = std::chrono::milliseconds(0));
  /// Queues a status report; a newer one replaces one not yet sent.
  void OfferStatus(const clutterseg::status_t& status);
  /// Waits until every frame offered so far is published (or dropped).
  void Flush();
  /// Publishes what waits (frames, then the last status) and stops the thread.
  void Finish();

  uint64_t frames_published() const { return frames_published_.load(); }
  /// objects_t messages the transport refused.
  uint64_t frames_failed() const { return frames_failed_.load(); }
  /// Frames dropped because the transport fell behind.
  uint64_t frames_dropped() const { return queue_.dropped(); }
  /// Every refused publish (objects, labels, status).
  uint64_t publish_failures() const { return bus_->failures(); }
  size_t queue_depth() const { return queue_.size(); }

 private:
  void Loop();
  void PublishPendingStatus();

  const LcmPublisherParams params_;
  LcmBus* const bus_;
  const OnPublished on_published_;
  SinkQueue<FrameMessages> queue_;
  std::thread thread_;
  std::mutex status_mutex_;
  clutterseg::status_t pending_status_;
  bool status_pending_{false};
  std::atomic<uint64_t> frames_published_{0};
  std::atomic<uint64_t> frames_failed_{0};
  std::mutex flush_mutex_;
  std::condition_variable flush_cv_;
  uint64_t handled_{0};  // (flush_mutex_) frames taken from the queue and published
};

}  // namespace clutterseg::daemon
