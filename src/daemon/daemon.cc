#include "clutterseg/daemon/daemon.h"

#include <pthread.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

#include "clutterseg/core/frame.h"
#include "clutterseg/core/frame_pool.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/daemon/latency_stats.h"
#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/pipeline/overlay.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/status_t.hpp"

namespace clutterseg::daemon {
namespace {

using Clock = std::chrono::steady_clock;
using config::LogLevel;

int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void SetThreadName(const char* name) { pthread_setname_np(pthread_self(), name); }

// One pipeline slot: a Segmenter with its buffers, the frame it works on and its output,
// which waits for the publisher. Fields marked (pipe) are guarded by Impl::pipe_mutex; the
// output fields are written by the lane while `frame` is set and read by the publisher while
// `output_ready` is set, so they need no lock.
struct Lane {
  int index{0};
  std::thread thread;
  std::unique_ptr<pipeline::Segmenter> segmenter;
  uint64_t params_generation{0};
  pipeline::SegmentationResult result;
  core::ColorImage base_image;
  core::ColorImage overlay;

  core::RgbdFrame* frame{nullptr};     // (pipe) assigned, being segmented
  core::RgbdFrame* finished{nullptr};  // (pipe) segmented; the dispatcher releases it
  bool output_ready{false};            // (pipe) output waits for the publisher

  bool ok{false};
  clutterseg::objects_t objects;
  clutterseg::label_image_t labels;
  int64_t receive_utime{0};
  double queue_ms{0.0};
  double segment_ms{0.0};
  std::array<double, kNumStages> stages{};
};

}  // namespace

const char* ToString(DeviceState state) {
  switch (state) {
    case DeviceState::kStarting:
      return "starting";
    case DeviceState::kStreaming:
      return "streaming";
    case DeviceState::kReconnecting:
      return "reconnecting";
    case DeviceState::kEndOfStream:
      return "end_of_stream";
    case DeviceState::kError:
      return "error";
  }
  return "error";
}

struct Daemon::Impl {
  config::DaemonConfig config;
  std::unique_ptr<core::FrameSource> source;
  LcmBus* bus{nullptr};
  std::string source_description;
  std::unique_ptr<core::FrameQueue> queue;
  std::unique_ptr<core::ThreadPool> pool;
  std::vector<std::unique_ptr<Lane>> lanes;
  std::thread capture_thread;
  std::thread dispatch_thread;
  std::thread publish_thread;
  Clock::time_point start_time{Clock::now()};
  bool started{false};
  bool joined{false};

  // Stop request and interruptible sleeps.
  std::atomic<bool> stop{false};
  std::mutex stop_mutex;
  std::condition_variable stop_cv;

  // Pipeline hand-offs.
  std::mutex pipe_mutex;
  std::condition_variable pipe_cv;
  uint64_t assigned{0};  // (pipe) frames given to lanes
  // (pipe) lane of the i-th frame assigned, at i % size (one entry per lane: a lane holds at
  // most one frame or output).
  std::vector<size_t> order;
  uint64_t consumed{0};  // (pipe) lane outputs taken by the publisher
  bool dispatch_done{false};
  bool lanes_exit{false};

  // Segmenter parameters, replaced by UpdateSegmenterParams.
  std::mutex params_mutex;
  pipeline::SegmenterParams params;
  std::atomic<uint64_t> params_generation{0};

  // Counters and state for status_t.
  std::atomic<uint64_t> captured{0};
  std::atomic<uint64_t> processed{0};
  std::atomic<uint64_t> published{0};
  std::atomic<uint64_t> discarded{0};
  std::atomic<uint64_t> reconnects{0};
  std::atomic<uint64_t> reloads{0};
  std::atomic<int> device_state{static_cast<int>(DeviceState::kStarting)};
  std::atomic<int> last_num_objects{0};

  mutable std::mutex error_mutex;
  bool failed{false};
  std::string first_error;
  std::string last_error;

  std::mutex done_mutex;
  std::condition_variable done_cv;
  bool finished{false};

  // ---- helpers ------------------------------------------------------------------------

  void RequestStop() {
    if (stop.exchange(true)) return;
    if (source) source->RequestStop();
    { std::lock_guard<std::mutex> lock(stop_mutex); }
    stop_cv.notify_all();
    { std::lock_guard<std::mutex> lock(pipe_mutex); }
    pipe_cv.notify_all();
  }

  // Sleeps for `d` unless a stop is requested; returns true when stopping.
  bool SleepUnlessStopped(std::chrono::microseconds d) {
    std::unique_lock<std::mutex> lock(stop_mutex);
    return stop_cv.wait_for(lock, d, [this] { return stop.load(); });
  }

  void NoteError(const std::string& message) {
    std::lock_guard<std::mutex> lock(error_mutex);
    last_error = message;
  }

  // Records a failure that ends the run with exit code 1.
  void Fail(const std::string& message) {
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!failed) first_error = message;
      failed = true;
      last_error = message;
    }
    Log(LogLevel::kError, message);
    RequestStop();
  }

  void SetDeviceState(DeviceState s) { device_state.store(static_cast<int>(s)); }
  DeviceState GetDeviceState() const { return static_cast<DeviceState>(device_state.load()); }

  // ---- capture thread -----------------------------------------------------------------

  void CaptureLoop() {
    SetThreadName("cs-capture");
    try {
      const bool live = source->IsLive();
      const bool lockstep = !live && config.speed == config::Speed::kMax;
      const bool pace = !live && config.speed == config::Speed::kRealtime;
      const auto min_backoff =
          std::chrono::microseconds(static_cast<int64_t>(config.reconnect_backoff_min_s * 1e6));
      const auto max_backoff =
          std::chrono::microseconds(static_cast<int64_t>(config.reconnect_backoff_max_s * 1e6));
      int64_t pace_utime0 = 0;
      Clock::time_point pace_t0;
      bool pace_base = false;
      SetDeviceState(DeviceState::kStreaming);
      bool running = true;
      while (running && !stop.load()) {
        if (lockstep && config.max_frames > 0 &&
            captured.load() >= static_cast<uint64_t>(config.max_frames)) {
          break;
        }
        if (lockstep && !queue->wait_not_full_for(std::chrono::milliseconds(100))) continue;
        core::RgbdFrame* frame = queue->acquire();
        frame->receive_utime = 0;
        switch (source->Read(100, frame)) {
          case core::ReadStatus::kOk: {
            if (frame->receive_utime == 0) frame->receive_utime = core::SteadyClockMicros();
            frame->camera_name = config.camera_name;
            if (pace) {
              // Replay at the recorded rate: frame time relative to the first frame.
              const auto now = Clock::now();
              if (!pace_base || frame->utime < pace_utime0) {
                pace_utime0 = frame->utime;
                pace_t0 = now;
                pace_base = true;
              }
              const auto due = pace_t0 + std::chrono::microseconds(frame->utime - pace_utime0);
              if (due - now > std::chrono::seconds(2)) {  // a jump in the recording's clock
                pace_utime0 = frame->utime;
                pace_t0 = now;
              } else if (due > now &&
                         SleepUnlessStopped(
                             std::chrono::duration_cast<std::chrono::microseconds>(due - now))) {
                break;
              }
            }
            queue->push();
            captured.fetch_add(1);
            if (GetDeviceState() != DeviceState::kStreaming)
              SetDeviceState(DeviceState::kStreaming);
            break;
          }
          case core::ReadStatus::kTimeout:
            break;
          case core::ReadStatus::kEndOfStream:
            if (stop.load()) {
              running = false;
            } else if (config.loop) {
              source->Close();
              source->Open();
              pace_base = false;
            } else {
              Log(LogLevel::kInfo, "end of stream: " + source_description);
              SetDeviceState(DeviceState::kEndOfStream);
              running = false;
            }
            break;
          case core::ReadStatus::kDisconnected:
            Reconnect(min_backoff, max_backoff);
            break;
          case core::ReadStatus::kError:
            SetDeviceState(DeviceState::kError);
            Fail("source error: " + source->last_error());
            running = false;
            break;
        }
      }
    } catch (const std::exception& e) {
      SetDeviceState(DeviceState::kError);
      Fail(std::string("capture failed: ") + e.what());
    } catch (...) {
      SetDeviceState(DeviceState::kError);
      Fail("capture failed: unknown exception");
    }
    queue->close();
    try {
      source->Close();
    } catch (const std::exception& e) {
      NoteError(std::string("closing the source: ") + e.what());
    } catch (...) {
    }
  }

  void Reconnect(std::chrono::microseconds min_backoff, std::chrono::microseconds max_backoff) {
    const std::string why = "device lost: " + source->last_error();
    Log(LogLevel::kWarn, why + "; reconnecting");
    NoteError(why);
    SetDeviceState(DeviceState::kReconnecting);
    try {
      source->Close();
    } catch (const std::exception& e) {
      NoteError(std::string("closing the lost device: ") + e.what());
    }
    auto backoff = min_backoff;
    while (!SleepUnlessStopped(backoff)) {
      reconnects.fetch_add(1);
      try {
        source->Open();
        SetDeviceState(DeviceState::kStreaming);
        Log(LogLevel::kInfo, "reconnected: " + source->Describe());
        return;
      } catch (const std::exception& e) {
        NoteError(std::string("reconnect failed: ") + e.what());
        Log(LogLevel::kWarn, std::string("reconnect failed: ") + e.what());
      }
      backoff = std::min(backoff * 2, max_backoff);
    }
  }

  // ---- dispatcher thread ---------------------------------------------------------------

  // Hands segmented frames back to the queue. Dispatcher thread only, pipe_mutex held.
  void ReleaseFinishedLocked() {
    for (auto& lane : lanes) {
      if (lane->finished != nullptr) {
        queue->release(lane->finished);
        lane->finished = nullptr;
      }
    }
  }

  void DispatchLoop() {
    SetThreadName("cs-dispatch");
    try {
      for (;;) {
        {
          std::lock_guard<std::mutex> lock(pipe_mutex);
          ReleaseFinishedLocked();
        }
        core::RgbdFrame* frame = queue->wait_pop_for(std::chrono::milliseconds(100));
        if (frame == nullptr) {
          if (queue->drained()) break;
          continue;
        }
        if (stop.load()) {  // finish only what is in flight
          queue->release(frame);
          discarded.fetch_add(1);
          continue;
        }
        std::unique_lock<std::mutex> lock(pipe_mutex);
        // Latency first: the frame goes to the lowest free lane (its Segmenter's buffers are
        // warm), and while another lane is segmenting it waits for that lane (which then has
        // the pool to itself and finishes sooner) unless newer frames queue up behind it: then
        // the lanes pipeline to keep up. Queue arrivals are not signalled, hence the short
        // polls while a frame is held back.
        size_t k = lanes.size();
        for (;;) {
          ReleaseFinishedLocked();
          k = lanes.size();
          bool busy = false;
          for (size_t l = lanes.size(); l-- > 0;) {
            if (lanes[l]->frame == nullptr && !lanes[l]->output_ready) k = l;
            busy = busy || lanes[l]->frame != nullptr;
          }
          const bool have_lane = k < lanes.size();
          if (have_lane && (!busy || queue->size() > 0 || stop.load())) break;
          pipe_cv.wait_for(lock, std::chrono::milliseconds(have_lane ? 1 : 100));
        }
        lanes[k]->frame = frame;
        order[assigned % order.size()] = k;  // the publisher takes outputs in this order
        ++assigned;
        lock.unlock();
        pipe_cv.notify_all();
      }
    } catch (const std::exception& e) {
      Fail(std::string("dispatch failed: ") + e.what());
    } catch (...) {
      Fail("dispatch failed: unknown exception");
    }
    // Let the lanes finish, then tell them and the publisher that nothing more comes.
    {
      std::unique_lock<std::mutex> lock(pipe_mutex);
      pipe_cv.wait(lock, [&] {
        ReleaseFinishedLocked();
        return std::all_of(lanes.begin(), lanes.end(),
                           [](const auto& l) { return l->frame == nullptr; });
      });
      ReleaseFinishedLocked();
      // Frames still waiting (after a failure) are discarded.
      while (core::RgbdFrame* f = queue->try_pop()) {
        queue->release(f);
        discarded.fetch_add(1);
      }
      dispatch_done = true;
      lanes_exit = true;
    }
    pipe_cv.notify_all();
  }

  // ---- lane threads ---------------------------------------------------------------------

  void LaneLoop(Lane* lane) {
    char name[16];
    std::snprintf(name, sizeof(name), "cs-lane%d", lane->index);
    SetThreadName(name);
    for (;;) {
      core::RgbdFrame* frame = nullptr;
      {
        std::unique_lock<std::mutex> lock(pipe_mutex);
        pipe_cv.wait(lock, [&] { return lane->frame != nullptr || lanes_exit; });
        if (lane->frame == nullptr) return;
        frame = lane->frame;
      }
      ProcessFrame(lane, *frame);
      {
        std::lock_guard<std::mutex> lock(pipe_mutex);
        lane->finished = frame;
        lane->frame = nullptr;
        lane->output_ready = true;
      }
      pipe_cv.notify_all();
    }
  }

  // Segments one frame into the lane's output. Never throws.
  void ProcessFrame(Lane* lane, const core::RgbdFrame& frame) {
    lane->ok = false;
    try {
      const int64_t start_us = core::SteadyClockMicros();
      lane->receive_utime = frame.receive_utime;
      lane->queue_ms = static_cast<double>(start_us - frame.receive_utime) * 1e-3;
      const uint64_t generation = params_generation.load();
      if (generation != lane->params_generation) {
        pipeline::SegmenterParams p;
        {
          std::lock_guard<std::mutex> lock(params_mutex);
          p = params;
        }
        lane->segmenter = std::make_unique<pipeline::Segmenter>(p, pool.get());
        lane->params_generation = generation;
      }
      const core::ColorImage* color =
          (!frame.color.empty() && frame.color.width == frame.depth.width &&
           frame.color.height == frame.depth.height)
              ? &frame.color
              : nullptr;
      // One frame in flight (a camera at 30 Hz): the pool splits it over the cores for the
      // lowest latency. Several in flight (replay at full speed): every core already runs a
      // lane, so the pool runs each lane's work inline until only one lane is left, whose
      // remaining stages then fan out again. The output is the same either way.
      const core::ThreadPool::ActiveCaller active(pool.get());
      lane->segmenter->SetPool(pool.get());
      lane->segmenter->ProcessDepth(frame.depth, color, frame.intrinsics, &lane->result);
      lane->segment_ms = static_cast<double>(core::SteadyClockMicros() - start_us) * 1e-3;
      lane->stages = StageValues(lane->result.times);

      FrameInfo info;
      info.utime = frame.utime;
      info.frame_seq = static_cast<int64_t>(frame.sequence);
      info.camera_name = frame.camera_name;
      info.intrinsics = frame.intrinsics;
      ToObjectsMessage(lane->result, info, &lane->objects);
      if (config.publish_labels) {
        EncodeLabelImage(lane->result.labels, info, config.label_compression, &lane->labels);
      }
      if (!config.png_dir.empty()) {
        pipeline::CloudToImage(lane->segmenter->working_cloud(), &lane->base_image);
        pipeline::RenderOverlay(lane->result.labels, &lane->base_image, &lane->overlay);
        char file[64];
        std::snprintf(file, sizeof(file), "/frame_%06lld.png",
                      static_cast<long long>(frame.sequence));
        io::WriteColorPng(config.png_dir + file, lane->overlay);
      }
      processed.fetch_add(1);
      lane->ok = true;
    } catch (const std::exception& e) {
      Fail("processing frame " + std::to_string(frame.sequence) + " failed: " + e.what());
    } catch (...) {
      Fail("processing frame " + std::to_string(frame.sequence) + " failed: unknown exception");
    }
  }

  // ---- publisher thread -------------------------------------------------------------------

  struct PublisherState {
    LatencyWindow segment;
    LatencyWindow queue_wait;
    LatencyWindow capture_to_publish;
    std::array<LatencyWindow, kNumStages> stages;
    uint64_t last_published{0};
    Clock::time_point last_status{Clock::now()};
    clutterseg::status_t status;
  };

  void PublishLane(Lane* lane, PublisherState* ps) {
    if (!lane->ok) return;
    if (config.max_frames > 0 && published.load() >= static_cast<uint64_t>(config.max_frames)) {
      return;
    }
    const int64_t now_us = core::SteadyClockMicros();
    const double c2p_ms = static_cast<double>(now_us - lane->receive_utime) * 1e-3;
    lane->objects.queue_ms = static_cast<float>(lane->queue_ms);
    lane->objects.capture_to_publish_ms = static_cast<float>(c2p_ms);
    bus->PublishMessage(config.objects_channel, lane->objects);
    if (config.publish_labels) bus->PublishMessage(config.labels_channel, lane->labels);
    ps->segment.Add(lane->segment_ms);
    ps->queue_wait.Add(lane->queue_ms);
    ps->capture_to_publish.Add(c2p_ms);
    for (size_t i = 0; i < kNumStages; ++i) ps->stages[i].Add(lane->stages[i]);
    last_num_objects.store(lane->objects.num_objects);
    const uint64_t n = published.fetch_add(1) + 1;
    if (config.max_frames > 0 && n >= static_cast<uint64_t>(config.max_frames)) {
      Log(LogLevel::kInfo, "published " + std::to_string(n) + " frames (max_frames); stopping");
      RequestStop();
    }
  }

  void PublishStatus(PublisherState* ps) {
    const auto now = Clock::now();
    const double period_s = std::chrono::duration<double>(now - ps->last_status).count();
    ps->last_status = now;
    const uint64_t pub = published.load();
    const double fps =
        period_s > 0 ? static_cast<double>(pub - ps->last_published) / period_s : 0.0;
    ps->last_published = pub;
    const LatencySummary seg = ps->segment.TakeSummary();
    const LatencySummary qw = ps->queue_wait.TakeSummary();
    const LatencySummary c2p = ps->capture_to_publish.TakeSummary();

    clutterseg::status_t& s = ps->status;
    s.utime = WallMicros();
    s.camera_name = config.camera_name;
    s.source = source_description;
    s.fps = static_cast<float>(fps);
    s.uptime_s = static_cast<float>(std::chrono::duration<double>(now - start_time).count());
    s.segment_p50_ms = static_cast<float>(seg.p50_ms);
    s.segment_p99_ms = static_cast<float>(seg.p99_ms);
    s.queue_p50_ms = static_cast<float>(qw.p50_ms);
    s.queue_p99_ms = static_cast<float>(qw.p99_ms);
    s.capture_to_publish_p50_ms = static_cast<float>(c2p.p50_ms);
    s.capture_to_publish_p99_ms = static_cast<float>(c2p.p99_ms);
    s.num_stages = static_cast<int32_t>(kNumStages);
    s.stage_names.resize(kNumStages);
    s.stage_p50_ms.resize(kNumStages);
    s.stage_p99_ms.resize(kNumStages);
    for (size_t i = 0; i < kNumStages; ++i) {
      const LatencySummary st = ps->stages[i].TakeSummary();
      s.stage_names[i] = StageNames()[i];
      s.stage_p50_ms[i] = static_cast<float>(st.p50_ms);
      s.stage_p99_ms[i] = static_cast<float>(st.p99_ms);
    }
    s.queue_depth = static_cast<int32_t>(queue->size());
    s.queue_capacity = static_cast<int32_t>(queue->capacity());
    s.frames_captured = static_cast<int64_t>(captured.load());
    s.frames_processed = static_cast<int64_t>(processed.load());
    s.frames_dropped = static_cast<int64_t>(queue->dropped());
    s.publish_failures = static_cast<int64_t>(bus->failures());
    s.last_num_objects = last_num_objects.load();
    const DeviceState state = GetDeviceState();
    s.device_state = static_cast<int8_t>(state);
    s.device_state_name = ToString(state);
    s.reconnect_attempts = static_cast<int32_t>(reconnects.load());
    {
      std::lock_guard<std::mutex> lock(error_mutex);
      s.last_error = last_error;
    }
    bus->PublishMessage(config.status_channel, s);

    if (LogEnabled(LogLevel::kInfo)) {
      std::fprintf(stderr,
                   "clutterseg: %5.1f fps | segment p50 %6.1f p99 %6.1f ms | capture->publish "
                   "p50 %6.1f p99 %6.1f ms | objects %d | queue %d/%d | dropped %lld | "
                   "published %llu | %s%s\n",
                   fps, seg.p50_ms, seg.p99_ms, c2p.p50_ms, c2p.p99_ms, s.last_num_objects,
                   s.queue_depth, s.queue_capacity, static_cast<long long>(s.frames_dropped),
                   static_cast<unsigned long long>(pub), s.device_state_name.c_str(),
                   s.publish_failures > 0
                       ? (" | publish failures " + std::to_string(s.publish_failures)).c_str()
                       : "");
    }
  }

  void PublishLoop() {
    SetThreadName("cs-publish");
    auto ps = std::make_unique<PublisherState>();
    const auto period =
        std::chrono::microseconds(static_cast<int64_t>(config.status_period_s * 1e6));
    auto next_status = Clock::now() + period;
    for (;;) {
      Lane* ready = nullptr;
      bool done = false;
      {
        std::unique_lock<std::mutex> lock(pipe_mutex);
        // The next output in frame order, once its lane has it.
        auto next_ready = [&]() -> Lane* {
          if (consumed == assigned) return nullptr;
          Lane* l = lanes[order[consumed % order.size()]].get();
          return l->output_ready ? l : nullptr;
        };
        pipe_cv.wait_until(lock, next_status, [&] {
          return next_ready() != nullptr || (dispatch_done && consumed == assigned);
        });
        ready = next_ready();
        if (ready == nullptr && dispatch_done && consumed == assigned) done = true;
      }
      if (ready != nullptr) {
        try {
          PublishLane(ready, ps.get());
        } catch (const std::exception& e) {
          Fail(std::string("publishing failed: ") + e.what());
        } catch (...) {
          Fail("publishing failed: unknown exception");
        }
        {
          std::lock_guard<std::mutex> lock(pipe_mutex);
          ready->output_ready = false;
          ++consumed;
        }
        pipe_cv.notify_all();
      }
      if (done) break;
      if (Clock::now() >= next_status) {
        try {
          PublishStatus(ps.get());
        } catch (const std::exception& e) {
          NoteError(std::string("status: ") + e.what());
        } catch (...) {
        }
        next_status = std::max(next_status + period, Clock::now());
      }
    }
    try {
      PublishStatus(ps.get());  // the final state (end of stream, error, counters)
    } catch (...) {
    }
    {
      std::lock_guard<std::mutex> lock(done_mutex);
      finished = true;
    }
    done_cv.notify_all();
  }
};

Daemon::Daemon(const config::DaemonConfig& config, std::unique_ptr<core::FrameSource> source,
               LcmBus* bus)
    : impl_(std::make_unique<Impl>()) {
  config.ValidateOrThrow();
  CLUTTERSEG_DEMAND(source != nullptr && bus != nullptr);
  Impl& d = *impl_;
  d.config = config;
  d.source = std::move(source);
  d.bus = bus;
  d.params = config.segmenter;
  SetLogLevel(config.log_level);
  const size_t depth = static_cast<size_t>(config.pipeline_depth);
  core::FramePoolParams pool_params;
  pool_params.capacity = static_cast<size_t>(config.queue_capacity);
  pool_params.max_consumer_held = depth + 1;
  d.queue = core::MakeFrameQueue(pool_params);
  d.pool = std::make_unique<core::ThreadPool>(config.threads);
  for (size_t i = 0; i < depth; ++i) {
    auto lane = std::make_unique<Lane>();
    lane->index = static_cast<int>(i);
    lane->segmenter = std::make_unique<pipeline::Segmenter>(config.segmenter, d.pool.get());
    d.lanes.push_back(std::move(lane));
  }
  d.order.assign(depth, 0);
}

Daemon::~Daemon() {
  if (impl_->started && !impl_->joined) {
    impl_->RequestStop();
    Join();
  }
}

void Daemon::Start() {
  Impl& d = *impl_;
  CLUTTERSEG_DEMAND(!d.started);
  try {
    d.source->Open();
  } catch (const std::exception& e) {
    throw SourceOpenError(e.what());
  }
  d.source_description = d.source->Describe();
  if (!d.config.png_dir.empty()) std::filesystem::create_directories(d.config.png_dir);
  d.start_time = Clock::now();
  d.started = true;
  for (auto& lane : d.lanes) {
    Lane* l = lane.get();
    l->thread = std::thread([&d, l] { d.LaneLoop(l); });
  }
  d.publish_thread = std::thread([&d] { d.PublishLoop(); });
  d.dispatch_thread = std::thread([&d] { d.DispatchLoop(); });
  d.capture_thread = std::thread([&d] { d.CaptureLoop(); });
}

void Daemon::RequestStop() { impl_->RequestStop(); }

void Daemon::UpdateSegmenterParams(const pipeline::SegmenterParams& params) {
  params.ValidateOrThrow();
  {
    std::lock_guard<std::mutex> lock(impl_->params_mutex);
    impl_->params = params;
  }
  impl_->params_generation.fetch_add(1);
  impl_->reloads.fetch_add(1);
}

bool Daemon::WaitFor(std::chrono::milliseconds timeout) {
  if (!impl_->started) return true;
  std::unique_lock<std::mutex> lock(impl_->done_mutex);
  return impl_->done_cv.wait_for(lock, timeout, [this] { return impl_->finished; });
}

void Daemon::Join() {
  Impl& d = *impl_;
  if (!d.started || d.joined) return;
  if (d.capture_thread.joinable()) d.capture_thread.join();
  if (d.dispatch_thread.joinable()) d.dispatch_thread.join();
  for (auto& lane : d.lanes) {
    if (lane->thread.joinable()) lane->thread.join();
  }
  if (d.publish_thread.joinable()) d.publish_thread.join();
  d.joined = true;
}

int Daemon::exit_code() const {
  std::lock_guard<std::mutex> lock(impl_->error_mutex);
  return impl_->failed ? kExitRuntimeError : kExitOk;
}

std::string Daemon::error() const {
  std::lock_guard<std::mutex> lock(impl_->error_mutex);
  return impl_->first_error;
}

DaemonStats Daemon::stats() const {
  const Impl& d = *impl_;
  DaemonStats s;
  s.frames_captured = d.captured.load();
  s.frames_processed = d.processed.load();
  s.frames_published = d.published.load();
  s.frames_dropped = d.queue->dropped();
  s.frames_discarded = d.discarded.load();
  s.publish_failures = d.bus->failures();
  s.reconnect_attempts = d.reconnects.load();
  s.param_reloads = d.reloads.load();
  s.device_state = static_cast<DeviceState>(d.device_state.load());
  return s;
}

std::string Daemon::source_description() const { return impl_->source_description; }

}  // namespace clutterseg::daemon
