#include "clutterseg/daemon/daemon.h"

#include <pthread.h>

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "clutterseg/core/frame.h"
#include "clutterseg/core/frame_pool.h"
#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/lcm_publisher.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/daemon/overlay_writer.h"
#include "clutterseg/daemon/source_factory.h"
#include "clutterseg/pipeline/decimation.h"
#include "clutterseg/pipeline/frame_runner.h"
#include "clutterseg/pipeline/overlay.h"
#include "clutterseg/pipeline/partition_prior.h"
#include "clutterseg/pipeline/temporal_filter.h"
#include "clutterseg/pipeline/tracker.h"

namespace clutterseg::daemon {
namespace {

// What a lane leaves for the ordered completion: the frame's messages and overlay input.
// (The frame itself may be back in the queue by then.)
struct LaneOutput {
  uint64_t sequence{0};
  std::shared_ptr<const core::Extrinsics> extrinsics;  // the pose this frame is published in
  FrameInfo info;
  float queue_ms{0.f};
  FrameMessages messages;
  OverlayFrame overlay;
};

std::shared_ptr<const core::Extrinsics> ToShared(std::optional<core::Extrinsics> e) {
  return e ? std::make_shared<const core::Extrinsics>(std::move(*e)) : nullptr;
}

}  // namespace

struct Daemon::Impl {
  Impl(const DaemonConfig& c, std::unique_ptr<core::FrameSource> s, LcmBus* b)
      : config((c.ValidateOrThrow(), c)),
        extrinsics(ToShared(LoadExtrinsics(c.camera))),
        source(std::move(s)),
        bus(b),
        queue(core::MakeFrameQueue(
            core::FramePoolParams{static_cast<size_t>(c.capture.queue_capacity),
                                  static_cast<size_t>(c.processing.pipeline_depth) + 1})),
        outputs(static_cast<size_t>(c.processing.pipeline_depth)),
        capture(c.capture, source.get(), queue.get(), [this](const std::string& e) { Fail(e); }),
        publisher(c.lcm, bus,
                  [this](const FrameMessages& f, bool) {
                    status->Record(f.segment_ms, f.objects.queue_ms,
                                   f.objects.capture_to_publish_ms, f.objects.times);
                  }),
        runner(
            pipeline::ForDecimatedFrames(c.segmenter, c.camera.decimation), c.processing,
            [this](const pipeline::FrameRunner::Lane& lane, uint64_t item) {
              Segment(lane, reinterpret_cast<const core::RgbdFrame*>(item));
            },
            [this](const pipeline::FrameRunner::Lane& lane, uint64_t item,
                   const std::string* error) { Complete(lane, item, error); }) {
    if (config.overlay.enabled()) overlay = std::make_unique<OverlayWriter>(config.overlay);
    if (config.track_objects) {
      tracker = std::make_unique<pipeline::Tracker>(config.tracker, config.segmenter.temporal,
                                                    runner.pool());
    }
    if (extrinsics) {
      Log(LogLevel::kInfo, "objects in frame '" + extrinsics->parent_frame + "' (" +
                               config.camera.extrinsics_file + ")");
    }
    SetTemporalFilter(config.segmenter.temporal);
    SetPartitionPrior(config.segmenter);
  }

  const DaemonConfig config;
  // camera.extrinsics_file: publish in its parent frame; null = the camera frame. Replaced
  // by a reload (UpdateExtrinsics); each lane takes the current one when its frame starts.
  std::shared_ptr<const core::Extrinsics> extrinsics;  // (extrinsics_mutex)
  std::mutex extrinsics_mutex;
  std::unique_ptr<core::FrameSource> source;
  LcmBus* bus;
  std::string source_description;
  std::unique_ptr<core::FrameQueue> queue;
  std::vector<LaneOutput> outputs;  // per lane
  Capture capture;
  LcmPublisher publisher;
  std::unique_ptr<OverlayWriter> overlay;
  std::unique_ptr<StatusReporter> status;  // made at Start, once the source is described
  // The tracker runs in the ordered completion (one call at a time, in frame order).
  std::unique_ptr<pipeline::Tracker> tracker;
  pipeline::TrackingResult tracking;
  std::mutex tracker_params_mutex;
  std::unique_ptr<pipeline::TrackerParams> pending_tracker_params;  // applied before a frame
  // The temporal depth filter: frames of a stream only (IsFrameStream), applied by the
  // dispatcher to each frame before it is submitted, so in frame order whatever the lanes.
  const bool stream_source{IsFrameStream(config.source)};
  std::unique_ptr<pipeline::TemporalDepthFilter> temporal;  // dispatcher thread only
  bool have_filtered_sequence{false};                       // dispatcher thread only
  uint64_t last_filtered_sequence{0};                       // dispatcher thread only
  std::mutex temporal_params_mutex;
  std::unique_ptr<pipeline::TemporalFilterParams> pending_temporal_params;  // applied next
  // The partition prior: applied in the ordered completion (frame order), streams only.
  std::unique_ptr<pipeline::PartitionPrior> partition;  // ordered completion only
  std::mutex partition_params_mutex;
  std::unique_ptr<pipeline::SegmenterParams> pending_partition_params;  // applied next
  pipeline::FrameRunner runner;  // last: its lanes use everything above
  std::thread dispatch_thread;
  bool opened{false};
  bool started{false};
  bool joined{false};

  std::atomic<bool> stop{false};
  std::atomic<bool> interrupted{false};  // stopped from outside (a signal), not by the run
  std::atomic<uint64_t> processed{0};
  std::atomic<uint64_t> handed{0};  // frames handed to the sinks
  std::atomic<uint64_t> discarded{0};
  std::atomic<uint64_t> reloads{0};
  std::atomic<int> last_num_objects{0};
  std::atomic<uint64_t> frames_capped{0};  // frames that reached a segmenter cap
  uint64_t no_depth_streak{0};  // (ordered completion) frames in a row without a point in range
  // How long the ordered completion waits for room in a full sink queue before the oldest
  // frame there is dropped: none for a camera or a paced replay (a sink that falls behind
  // costs frames, never capture time), kLockstepSinkWait for a recording replayed in lockstep
  // (speed max), whose frames are all to be delivered; set by Start.
  std::chrono::milliseconds sink_wait{0};
  // Longer than any scheduling hiccup of a sink thread, shorter than the drain's 5 s.
  static constexpr std::chrono::milliseconds kLockstepSinkWait{2000};

  mutable std::mutex error_mutex;
  bool failed{false};
  std::string first_error;

  std::mutex done_mutex;
  std::condition_variable done_cv;
  bool finished{false};

  void RequestStop() {
    if (stop.exchange(true)) return;
    capture.RequestStop();
    runner.Close();
  }

  // Records a failure that ends the run with exit code 1.
  void Fail(const std::string& message) {
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!failed) first_error = message;
      failed = true;
    }
    Log(LogLevel::kError, message);
    RequestStop();
  }

  std::string LastError() const {
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (failed) return first_error;
    }
    const std::string overlay_error = overlay ? overlay->last_error() : std::string();
    return overlay_error.empty() ? capture.last_problem() : "overlay: " + overlay_error;
  }

  // ---- a lane: segments one frame into its output (FrameRunner::Work) ------------------

  // The objects and labels messages of the lane's result (and the overlay's labels). Run by
  // the lane after segmenting, and again in the ordered completion when the partition prior
  // changed the result.
  void DescribeObjects(const pipeline::FrameRunner::Lane& lane, LaneOutput* out) {
    const pipeline::SegmentationResult& result = *lane.result;
    FrameMessages& m = out->messages;
    ToObjectsMessage(result, out->info, &m.objects);
    m.objects.queue_ms = out->queue_ms;
    if (config.lcm.object_points > 0) {
      SampleObjectPoints(lane.segmenter->working_cloud(), result.labels, config.lcm.object_points,
                         &m.objects);
    }
    if (out->extrinsics) {
      ToParentFrame(*out->extrinsics, lane.segmenter->working_cloud(), result.labels, &m.objects);
    }
    m.has_labels = config.lcm.publish_labels;
    if (m.has_labels) {
      EncodeLabelImage(result.labels, out->info, config.lcm.label_compression, &m.labels);
    }
  }

  void Segment(const pipeline::FrameRunner::Lane& lane, const core::RgbdFrame* frame) {
    LaneOutput& out = outputs[static_cast<size_t>(lane.index)];
    out.sequence = frame->sequence;
    const int64_t start_us = core::SteadyClockMicros();
    pipeline::SegmentationResult& result = *lane.result;
    const bool have_color = !frame->color.empty() && frame->color.width == frame->depth.width &&
                            frame->color.height == frame->depth.height;
    if (!frame->cloud.empty()) {  // the source's own points (PCD files): segmented as they are
      lane.segmenter->Process(frame->cloud, frame->intrinsics, &result);
    } else {
      lane.segmenter->ProcessDepth(frame->depth, have_color ? &frame->color : nullptr,
                                   frame->intrinsics, &result);
    }
    FrameMessages& m = out.messages;
    m.receive_utime = frame->receive_utime;
    m.segment_ms = static_cast<double>(core::SteadyClockMicros() - start_us) * 1e-3;
    FrameInfo& info = out.info;
    info.utime = frame->host_utime;
    info.device_utime = frame->utime;
    info.frame_seq = static_cast<int64_t>(frame->sequence);
    info.camera_name = frame->camera_name;
    info.intrinsics = frame->intrinsics;
    out.queue_ms = static_cast<float>(static_cast<double>(start_us - frame->receive_utime) * 1e-3);
    {
      std::lock_guard<std::mutex> lock(extrinsics_mutex);
      out.extrinsics = extrinsics;
    }
    DescribeObjects(lane, &out);
    m.has_depth = config.lcm.publish_depth && !frame->depth.empty();
    if (m.has_depth) EncodeDepthImage(frame->depth, info, true, &m.depth);
    if (overlay) {
      out.overlay.sequence = frame->sequence;
      out.overlay.labels = result.labels;
      if (result.labels.width != frame->depth.width && !frame->cloud.empty()) {
        pipeline::CloudToImage(frame->cloud, &out.overlay.base);  // an unorganized cloud
      } else if (have_color) {
        out.overlay.base = frame->color;
      } else {
        pipeline::DepthToImage(frame->depth, &out.overlay.base);
      }
    }
    processed.fetch_add(1);
  }

  // ---- ordered completion: frames in capture order to the sinks (FrameRunner::Done) ----

  // Counts a frame that reached the segmenter's caps; the first one and every 1000th after
  // it are logged, naming the key.
  void NoteCapped(const pipeline::SegmentationResult& result) {
    const uint64_t n = frames_capped.fetch_add(1) + 1;
    if (n != 1 && n % 1000 != 0) return;
    const pipeline::SegmenterParams& p = config.segmenter;
    std::string what;
    if (result.supervoxels_capped) {
      what = "more seeds than segmenter.supervoxel.max_supervoxels = " +
             std::to_string(p.supervoxel.max_supervoxels) + " (some left out)";
    }
    if (result.objects_capped) {
      what += std::string(what.empty() ? "" : " and ") +
              "more objects than segmenter.objects.max_objects = " +
              std::to_string(p.objects.max_objects) + " (the smallest left as background)";
    }
    Log(LogLevel::kWarn, std::to_string(n) + (n == 1 ? " frame" : " frames") +
                             " so far reached a segmenter cap, the last with " + what);
  }

  // Frames in a row without one valid point in the depth range before the warning: one second
  // of a 30 Hz camera, and as many frames of a replay at any speed.
  static constexpr uint64_t kNoDepthWarnFrames = 30;

  // Warns once per run of frames without a valid point in the depth range (a depth PNG
  // directory in another unit, e.g. TUM RGB-D's 1/5000 m read as millimetres, puts every
  // point out of range: the frames are published, empty); notes when depth comes back.
  void NoteDepthInRange(uint32_t valid_points, uint64_t sequence) {
    if (valid_points > 0) {
      if (no_depth_streak >= kNoDepthWarnFrames) {
        Log(LogLevel::kInfo, "frame " + std::to_string(sequence) +
                                 " has valid depth in range again, after " +
                                 std::to_string(no_depth_streak) + " frames without");
      }
      no_depth_streak = 0;
      return;
    }
    if (++no_depth_streak != kNoDepthWarnFrames) return;
    const pipeline::PointsParams& range = config.segmenter.points;
    char limits[64];
    std::snprintf(limits, sizeof(limits), "%g..%g m", range.min_depth_m, range.max_depth_m);
    char scale[32];
    std::snprintf(scale, sizeof(scale), "%g", config.camera.depth_scale_mm);
    Log(LogLevel::kWarn,
        std::to_string(kNoDepthWarnFrames) + " frames in a row (up to frame " +
            std::to_string(sequence) + ") had no valid depth point within " + limits +
            ", so their objects_t are empty. Likely the depth unit: depth PNGs are read as "
            "millimetres unless camera.depth_scale_mm says otherwise (0.2 for TUM RGB-D's "
            "1/5000 m); camera.depth_scale_mm = " +
            scale +
            ". Otherwise check the range keys segmenter.points.min_depth_m and "
            "segmenter.points.max_depth_m, and the camera's view");
  }

  // Runs the second halves of the partition prior and the tracker (what they keep for the
  // next frame: PartitionPrior::Remember, Tracker::RememberSurfaces) when Complete returns,
  // after the frame was offered to the sinks, whatever path it returns by.
  struct RememberAfterPublishing {
    Impl* impl;
    pipeline::PartitionPrior* partition{nullptr};
    pipeline::Tracker* tracker{nullptr};
    explicit RememberAfterPublishing(Impl* i) : impl(i) {}
    RememberAfterPublishing(const RememberAfterPublishing&) = delete;
    RememberAfterPublishing& operator=(const RememberAfterPublishing&) = delete;
    ~RememberAfterPublishing() {
      try {
        if (partition != nullptr) partition->Remember();
        if (tracker != nullptr) tracker->RememberSurfaces();
      } catch (const std::exception& e) {
        impl->Fail(std::string("remembering the frame for the next one failed: ") + e.what());
      }
    }
  };

  void Complete(const pipeline::FrameRunner::Lane& lane, uint64_t, const std::string* error) {
    LaneOutput& out = outputs[static_cast<size_t>(lane.index)];
    if (error != nullptr) {
      Fail("processing frame " + std::to_string(out.sequence) + " failed: " + *error);
      return;
    }
    const int64_t max_frames = config.capture.max_frames;
    if (max_frames > 0 && handed.load() >= static_cast<uint64_t>(max_frames)) return;
    RememberAfterPublishing remember{this};
    ApplyPartitionPrior(lane, &out, &remember);
    if (tracker) {
      {
        std::lock_guard<std::mutex> lock(tracker_params_mutex);
        if (pending_tracker_params) {
          tracker->SetParams(*pending_tracker_params);
          pending_tracker_params.reset();
        }
      }
      // The ids first; the surfaces it keeps for the next frame once this one is published
      // (RememberAfterPublishing), off the capture-to-publish path.
      tracker->Associate(*lane.result, static_cast<int64_t>(out.sequence), &tracking,
                         lane.segmenter->working_cloud(), lane.segmenter->scene_depth());
      remember.tracker = tracker.get();
      ToTrackMessage(tracking, &out.messages.objects);
      if (out.extrinsics) LostTracksToParentFrame(*out.extrinsics, &out.messages.objects);
    }
    if (overlay) {
      pipeline::OverlayObjectsFrom(lane.result->objects, &out.overlay.objects);
      if (tracker) {
        for (pipeline::OverlayObject& o : out.overlay.objects) {  // result.objects[id - 1]
          if (o.id >= 1 && o.id <= tracking.objects.size()) {
            o.track_id = tracking.objects[o.id - 1].track_id;
          }
        }
      }
    }
    last_num_objects.store(out.messages.objects.num_objects);
    NoteDepthInRange(lane.result->num_valid_points, out.sequence);
    if (lane.result->supervoxels_capped || lane.result->objects_capped) NoteCapped(*lane.result);
    runner.RestIfIdle();  // the publisher gets a core at once (RememberAfterPublishing)
    publisher.Offer(&out.messages, sink_wait);
    // After a stop signal the overlays of the frames still in flight do not wait for room
    // behind the lowest-priority writer (in lockstep that wait is up to kLockstepSinkWait):
    // the oldest waiting one is dropped and counted instead.
    if (overlay) {
      overlay->Offer(&out.overlay, interrupted.load() ? std::chrono::milliseconds(0) : sink_wait);
    }
    const uint64_t n = handed.fetch_add(1) + 1;
    if (max_frames > 0 && n >= static_cast<uint64_t>(max_frames)) {
      Log(LogLevel::kInfo, "published " + std::to_string(n) + " frames (max_frames); stopping");
      RequestStop();
    }
  }

  // A new partition prior (its history starts afresh) or none: frames of a stream only, with
  // segmenter.partition.hold_frames > 1 or arrival_gap_frames > 0. Parameters equal to the running
  // prior's keep it. Ordered completion, or before the lanes start.
  void SetPartitionPrior(const pipeline::SegmenterParams& params) {
    const pipeline::SegmenterParams p =
        pipeline::ForDecimatedFrames(params, config.camera.decimation);
    if (partition && p.partition == partition->params() && p.temporal == partition->band()) {
      return;
    }
    partition.reset();
    if (stream_source && p.partition.enabled()) {
      partition =
          std::make_unique<pipeline::PartitionPrior>(p.partition, p.temporal, runner.pool());
    }
  }

  // The hysteresis on the partition, in frame order; a changed result is described again.
  // Armed in `remember` as soon as it relabelled, so that its second half runs whatever
  // path Complete leaves by.
  void ApplyPartitionPrior(const pipeline::FrameRunner::Lane& lane, LaneOutput* out,
                           RememberAfterPublishing* remember) {
    {
      std::lock_guard<std::mutex> lock(partition_params_mutex);
      if (pending_partition_params) {
        SetPartitionPrior(*pending_partition_params);
        // The tracker compares depths within the same band (one home: segmenter.temporal).
        if (tracker) tracker->SetBand(pending_partition_params->temporal);
        pending_partition_params.reset();
      }
    }
    if (!partition) return;
    const int64_t start_us = core::SteadyClockMicros();
    // Its output kept for the next frame once this one is published (RememberAfterPublishing).
    const bool changed =
        partition->Relabel(lane.segmenter->working_cloud(), static_cast<int64_t>(out->sequence),
                           lane.result, lane.segmenter->scene_depth());
    remember->partition = partition.get();
    if (changed) {
      DescribeObjects(lane, out);
      if (overlay) out->overlay.labels = lane.result->labels;
    }
    out->messages.segment_ms += static_cast<double>(core::SteadyClockMicros() - start_us) * 1e-3;
  }

  // ---- dispatcher: frame queue -> runner -> frame queue -----------------------------------

  // A new filter (its history starts afresh) or none. Dispatcher thread, or before it starts.
  // Parameters equal to the running filter's keep it and its history: a reload that changes
  // other keys does not make a still scene flicker.
  void SetTemporalFilter(const pipeline::TemporalFilterParams& params) {
    if (temporal && params == temporal->params()) return;
    temporal.reset();
    if (stream_source && params.enabled) {
      temporal = std::make_unique<pipeline::TemporalDepthFilter>(params);
    }
  }

  // Decimates (camera.decimation) and filters the frame's depth in place before it is
  // segmented (a cloud from the source is segmented as it is).
  void FilterDepth(core::RgbdFrame* frame) {
    pipeline::DecimateFrame(config.camera.decimation, frame);
    {
      std::lock_guard<std::mutex> lock(temporal_params_mutex);
      if (pending_temporal_params) {
        SetTemporalFilter(*pending_temporal_params);
        pending_temporal_params.reset();
      }
    }
    // A sequence number that does not increase is a restarted source (a reopened device):
    // its history starts afresh, as its tracks do (pipeline::Tracker).
    if (temporal && have_filtered_sequence && frame->sequence <= last_filtered_sequence) {
      temporal->Reset();
    }
    have_filtered_sequence = true;
    last_filtered_sequence = frame->sequence;
    if (temporal && frame->cloud.empty() && !frame->depth.empty()) {
      temporal->Apply(&frame->depth);
    }
  }

  void ReleaseFinished(std::vector<uint64_t>* items) {
    runner.TakeFinishedInputs(items);
    for (const uint64_t item : *items) queue->release(reinterpret_cast<core::RgbdFrame*>(item));
    items->clear();
  }

  void DispatchLoop() {
    pthread_setname_np(pthread_self(), "cs-dispatch");
    std::vector<uint64_t> finished_frames;
    finished_frames.reserve(outputs.size() + 1);
    const auto backlog = [this] { return stop.load() ? size_t{1} : queue->size(); };
    for (;;) {
      ReleaseFinished(&finished_frames);
      core::RgbdFrame* frame = queue->wait_pop_for(std::chrono::milliseconds(100));
      if (frame == nullptr) {
        if (queue->drained()) break;
        continue;
      }
      if (!stop.load()) FilterDepth(frame);
      if (stop.load() || !runner.Submit(reinterpret_cast<uint64_t>(frame), backlog)) {
        queue->release(frame);  // stopping: finish only what is in flight
        discarded.fetch_add(1);
      }
    }
    runner.Drain();
    ReleaseFinished(&finished_frames);
    if (runner.done_error().size() > 0) Fail("completing a frame failed: " + runner.done_error());
    // Everything segmented is handed on: let the sinks finish, then report the end.
    // A stop signal does not wait for the overlays still queued (the lowest-priority writer
    // may take seconds for them on a loaded machine): dropped and counted.
    if (overlay) overlay->Finish(interrupted.load());
    publisher.Flush();
    status->Finish();
    publisher.Finish();
    {
      std::lock_guard<std::mutex> lock(done_mutex);
      finished = true;
    }
    done_cv.notify_all();
  }

  // The counters of a status report; `report` is the source's (its copy costs strings: taken
  // once per call by the caller).
  StatusCounters Counters(const core::SourceReport& report) const {
    StatusCounters c;
    c.frames_captured = capture.captured();
    c.frames_processed = processed.load();
    c.frames_published = publisher.frames_published();
    c.frames_dropped = queue->dropped();
    c.frames_discarded = discarded.load();
    c.frames_publish_dropped = publisher.frames_dropped();
    if (overlay) {
      c.overlays_written = overlay->written();
      c.overlays_dropped = overlay->dropped();
      c.overlay_failures = overlay->failures();
    }
    c.publish_failures = publisher.publish_failures();
    c.reconnect_attempts = capture.reconnect_attempts();
    c.frames_not_delivered = report.frames_skipped();
    c.frames_expected = report.frames_in_source;
    c.queue_depth = static_cast<int32_t>(queue->size());
    c.queue_capacity = static_cast<int32_t>(queue->capacity());
    c.last_num_objects = last_num_objects.load();
    c.frames_capped = frames_capped.load();
    c.device_state = capture.device_state();
    c.last_error = LastError();
    return c;
  }
};

Daemon::Daemon(const DaemonConfig& config, std::unique_ptr<core::FrameSource> source, LcmBus* bus) {
  CLUTTERSEG_DEMAND(source != nullptr && bus != nullptr);
  impl_ = std::make_unique<Impl>(config, std::move(source), bus);
  SetLogLevel(config.log_level);
}

Daemon::~Daemon() {
  if (impl_->started && !impl_->joined) {
    impl_->RequestStop();
    Join();
  }
}

void Daemon::Open() {
  Impl& d = *impl_;
  CLUTTERSEG_DEMAND(!d.opened);
  try {
    d.source->Open();
  } catch (const std::exception& e) {
    throw SourceOpenError(e.what());
  }
  d.source_description = d.source->Describe();
  d.opened = true;
}

void Daemon::Start() {
  Impl& d = *impl_;
  CLUTTERSEG_DEMAND(!d.started);
  if (!d.opened) Open();
  if (d.overlay) d.overlay->Start();
  d.status = std::make_unique<StatusReporter>(
      d.config.status, d.config.capture.camera_name, d.source_description,
      [&d] { return d.Counters(d.source->report()); },
      [&d](const clutterseg::status_t& s) { d.publisher.OfferStatus(s); });
  d.started = true;
  if (!d.source->IsLive() && d.config.capture.speed == Speed::kMax) {
    d.sink_wait = Impl::kLockstepSinkWait;
  }
  d.publisher.Start();
  d.status->Start();
  d.dispatch_thread = std::thread([&d] { d.DispatchLoop(); });
  d.capture.Start();
}

void Daemon::RequestStop() {
  impl_->interrupted.store(true);
  impl_->RequestStop();
}

void Daemon::UpdateSegmenterParams(const pipeline::SegmenterParams& params) {
  // camera.decimation is fixed at start; the point counts follow it.
  impl_->runner.UpdateParams(
      pipeline::ForDecimatedFrames(params, impl_->config.camera.decimation));  // validates first
  {
    std::lock_guard<std::mutex> lock(impl_->temporal_params_mutex);
    impl_->pending_temporal_params =
        std::make_unique<pipeline::TemporalFilterParams>(params.temporal);
  }
  {
    std::lock_guard<std::mutex> lock(impl_->partition_params_mutex);
    impl_->pending_partition_params = std::make_unique<pipeline::SegmenterParams>(params);
  }
  impl_->reloads.fetch_add(1);
}

void Daemon::UpdateTrackerParams(const pipeline::TrackerParams& params) {
  params.ValidateOrThrow();
  std::lock_guard<std::mutex> lock(impl_->tracker_params_mutex);
  impl_->pending_tracker_params = std::make_unique<pipeline::TrackerParams>(params);
}

bool Daemon::UpdateExtrinsics(std::optional<core::Extrinsics> extrinsics) {
  std::shared_ptr<const core::Extrinsics> fresh = ToShared(std::move(extrinsics));
  std::lock_guard<std::mutex> lock(impl_->extrinsics_mutex);
  const core::Extrinsics* old = impl_->extrinsics.get();
  const bool changed = (old == nullptr) != (fresh == nullptr) || (old != nullptr && *old != *fresh);
  impl_->extrinsics = std::move(fresh);
  return changed;
}

bool Daemon::WaitFor(std::chrono::milliseconds timeout) {
  if (!impl_->started) return true;
  std::unique_lock<std::mutex> lock(impl_->done_mutex);
  return impl_->done_cv.wait_for(lock, timeout, [this] { return impl_->finished; });
}

void Daemon::Join() {
  Impl& d = *impl_;
  if (!d.started || d.joined) return;
  d.capture.Join();
  if (d.dispatch_thread.joinable()) d.dispatch_thread.join();
  d.joined = true;
}

int Daemon::exit_code() const {
  std::lock_guard<std::mutex> lock(impl_->error_mutex);
  return impl_->failed ? kExitFailure : kExitOk;
}

std::string Daemon::error() const {
  std::lock_guard<std::mutex> lock(impl_->error_mutex);
  return impl_->first_error;
}

DaemonStats Daemon::stats() const {
  const Impl& d = *impl_;
  DaemonStats s;
  s.source = d.source->report();
  static_cast<StatusCounters&>(s) = d.Counters(s.source);
  s.param_reloads = d.reloads.load();
  return s;
}

std::string Daemon::source_description() const { return impl_->source_description; }

RunLatency Daemon::run_latency() const {
  return impl_->status ? impl_->status->run_latency() : RunLatency{};
}

}  // namespace clutterseg::daemon
