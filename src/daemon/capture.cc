#include "clutterseg/daemon/capture.h"

#include <pthread.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/text_and_color.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/daemon/realtime.h"

namespace clutterseg::daemon {

using Clock = std::chrono::steady_clock;

namespace {

// A source that delivers no frame for this long while the daemon waits for one (a camera that
// stopped streaming: a loose cable, USB bandwidth, a driver that hung) is named in a warning.
constexpr std::chrono::seconds kNoFrameWarn{2};

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string OneDecimal(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", x);
  return buf;
}

}  // namespace

const char* ToString(Speed speed) { return speed == Speed::kMax ? "max" : "realtime"; }

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

void CaptureParams::ValidateOrThrow() const {
  const core::ParamCheck check("");
  check.InRange("processing.queue_capacity", queue_capacity, 1, 1024);
  check.Require(reconnect_backoff_min_s > 0.0 && reconnect_backoff_min_s <= 3600.0,
                "reconnect.backoff_min_s", reconnect_backoff_min_s, "(0, 3600] s");
  check.Require(
      reconnect_backoff_max_s >= reconnect_backoff_min_s && reconnect_backoff_max_s <= 3600.0,
      "reconnect.backoff_max_s", reconnect_backoff_max_s,
      ">= reconnect.backoff_min_s and <= 3600 s");
  check.NonEmpty("camera_name", camera_name, "a name");
  if (const int at = core::FirstControlCharacter(camera_name); at >= 0) {
    check.Fail("camera_name", "a text with a control character at byte " + std::to_string(at),
               "a name without control characters (it is published in every message)");
  }
  check.AtLeast("processing.max_frames", max_frames, int64_t{0}, "(0 = no limit)");
}

Capture::Capture(const CaptureParams& params, core::FrameSource* source, core::FrameQueue* queue,
                 std::function<void(const std::string&)> on_error)
    : params_((params.ValidateOrThrow(), params)),
      source_(source),
      queue_(queue),
      on_error_(std::move(on_error)) {}

Capture::~Capture() {
  RequestStop();
  Join();
}

void Capture::Start() {
  thread_ = std::thread([this] { Loop(); });
}

void Capture::RequestStop() {
  if (stop_.exchange(true)) return;
  source_->RequestStop();
  { std::lock_guard<std::mutex> lock(stop_mutex_); }
  stop_cv_.notify_all();
}

void Capture::Join() {
  if (thread_.joinable()) thread_.join();
}

std::string Capture::last_problem() const {
  std::lock_guard<std::mutex> lock(problem_mutex_);
  return last_problem_;
}

void Capture::NoteProblem(const std::string& message) {
  std::lock_guard<std::mutex> lock(problem_mutex_);
  last_problem_ = message;
}

bool Capture::SleepUnlessStopped(std::chrono::microseconds d) {
  std::unique_lock<std::mutex> lock(stop_mutex_);
  return stop_cv_.wait_for(lock, d, [this] { return stop_.load(); });
}

void Capture::Loop() {
  pthread_setname_np(pthread_self(), "cs-capture");
  try {
    const bool live = source_->IsLive();
    const bool lockstep = !live && params_.speed == Speed::kMax;
    const bool pace = !live && params_.speed == Speed::kRealtime;
    int64_t pace_utime0 = 0;
    int64_t pace_last_utime = 0;
    Clock::time_point pace_t0;
    bool pace_base = false;
    SetState(DeviceState::kStreaming);
    bool running = true;
    // The last frame (or the start); whether the wait since then was named in a warning.
    Clock::time_point last_frame = Clock::now();
    bool no_frame_warned = false;
    while (running && !stop_.load()) {
      if (lockstep && params_.max_frames > 0 &&
          captured_.load() >= static_cast<uint64_t>(params_.max_frames)) {
        break;
      }
      if (lockstep && !queue_->wait_not_full_for(std::chrono::milliseconds(100))) continue;
      core::RgbdFrame* frame = queue_->acquire();
      frame->receive_utime = 0;
      const core::ReadStatus status = source_->Read(100, frame);
      LogSkips();
      switch (status) {
        case core::ReadStatus::kOk: {
          const int64_t steady_now = core::SteadyClockMicros();
          if (frame->receive_utime == 0) frame->receive_utime = steady_now;
          // The host time of capture: the moment it entered the process, on the system clock.
          frame->host_utime = core::SystemClockMicros() - (steady_now - frame->receive_utime);
          frame->camera_name = params_.camera_name;
          if (pace) {
            // Replay at the recorded rate: frame time relative to the first frame.
            const auto now = Clock::now();
            // A new base at the first frame and whenever the recording's clock goes back
            // (each pass of a looped recording starts at the first frame's time again).
            if (!pace_base || frame->utime < pace_last_utime) {
              pace_utime0 = frame->utime;
              pace_t0 = now;
              pace_base = true;
            }
            pace_last_utime = frame->utime;
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
          if (no_frame_warned) {
            Log(LogLevel::kInfo, "frames from " + source_->Describe() + " again, after " +
                                     OneDecimal(SecondsSince(last_frame)) + " s without");
            no_frame_warned = false;
          }
          last_frame = Clock::now();
          queue_->push();
          captured_.fetch_add(1);
          if (device_state() != DeviceState::kStreaming) SetState(DeviceState::kStreaming);
          break;
        }
        case core::ReadStatus::kTimeout:
          if (!no_frame_warned && !stop_.load() && Clock::now() - last_frame >= kNoFrameWarn) {
            Log(LogLevel::kWarn,
                "no frame from " + source_->Describe() + " for " +
                    OneDecimal(SecondsSince(last_frame)) +
                    " s; still waiting (a camera that stopped streaming: check its cable, power "
                    "and USB bandwidth). Frames captured so far: " +
                    std::to_string(captured_.load()));
            no_frame_warned = true;
          }
          break;
        case core::ReadStatus::kEndOfStream:
          if (stop_.load()) {
            running = false;
          } else if (params_.loop) {
            source_->Close();
            const ScopedNormalClass normal;  // the driver's threads never real-time
            source_->Open();
            pace_base = false;
            last_frame = Clock::now();
          } else {
            Log(LogLevel::kInfo, "end of stream: " + source_->Describe());
            SetState(DeviceState::kEndOfStream);
            running = false;
          }
          break;
        case core::ReadStatus::kDisconnected:
          Reconnect();
          last_frame = Clock::now();  // the reconnection logs its own waits
          break;
        case core::ReadStatus::kError:
          SetState(DeviceState::kError);
          on_error_("source error: " + source_->last_error());
          running = false;
          break;
      }
    }
    next_skip_check_ = {};
    LogSkips();  // the last skips, before the run's summary
  } catch (const std::exception& e) {
    SetState(DeviceState::kError);
    on_error_(std::string("capture failed: ") + e.what());
  } catch (...) {
    SetState(DeviceState::kError);
    on_error_("capture failed: unknown exception");
  }
  queue_->close();
  try {
    source_->Close();
  } catch (const std::exception& e) {
    NoteProblem(std::string("closing the source: ") + e.what());
  } catch (...) {
  }
}

void Capture::LogSkips() {
  // A report copies the recent skips (strings): taken a few times a second, not per frame.
  const auto now = Clock::now();
  if (now < next_skip_check_) return;
  next_skip_check_ = now + std::chrono::milliseconds(250);
  const core::SourceReport report = source_->report();
  if (report.frames_skipped() == skips_logged_) return;
  for (const core::SkippedFrame& skip : report.recent_skips) {
    if (skip.serial <= skips_logged_) continue;
    Log(LogLevel::kWarn,
        "frame not delivered by the source (" + std::string(core::ToString(skip.reason)) + ")" +
            (skip.count > 1 ? " x" + std::to_string(skip.count) : "") + ": " + skip.what);
  }
  skips_logged_ = report.frames_skipped();
}

void Capture::Reconnect() {
  const std::string why = "device lost: " + source_->last_error();
  Log(LogLevel::kWarn, why + "; reconnecting");
  NoteProblem(why);
  SetState(DeviceState::kReconnecting);
  try {
    source_->Close();
  } catch (const std::exception& e) {
    NoteProblem(std::string("closing the lost device: ") + e.what());
  }
  auto backoff =
      std::chrono::microseconds(static_cast<int64_t>(params_.reconnect_backoff_min_s * 1e6));
  const auto max_backoff =
      std::chrono::microseconds(static_cast<int64_t>(params_.reconnect_backoff_max_s * 1e6));
  while (!SleepUnlessStopped(backoff)) {
    reconnects_.fetch_add(1);
    try {
      {
        const ScopedNormalClass normal;  // the driver's threads never real-time
        source_->Open();
      }
      SetState(DeviceState::kStreaming);
      Log(LogLevel::kInfo, "reconnected: " + source_->Describe());
      return;
    } catch (const std::exception& e) {
      NoteProblem(std::string("reconnect failed: ") + e.what());
      Log(LogLevel::kWarn, std::string("reconnect failed: ") + e.what());
    }
    backoff = std::min(backoff * 2, max_backoff);
  }
}

}  // namespace clutterseg::daemon
