#pragma once

// A FrameSource over frames held in memory (testutil::TabletopFrames), with scripted device
// behaviour (live pacing, device loss, failing reopen, errors, a gate) that no file or camera here
// can produce on demand.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "clutterseg/core/frame_source.h"

namespace clutterseg::daemon::testutil {

struct Script {
  bool live{true};
  int period_us{0};                  ///< time per Read
  int total_frames{10};              ///< then kEndOfStream (-1 = endless)
  int disconnect_after{-1};          ///< kDisconnected once after this many frames
  int failed_reopens{0};             ///< Open() throws this many times after a disconnect
  int error_after{-1};               ///< kError after this many frames
  int gate_after{-1};                ///< Read blocks after this many frames until OpenGate()
  std::atomic<int>* opens{nullptr};  ///< counts Open() calls when set (outlives the source)
  /// Frame sequence numbers count from 0 after every Open(), as a reopened OpenNI2 device's
  /// do (false: they continue across a reopen).
  bool sequence_from_open{false};
};

class ScriptedSource final : public core::FrameSource {
 public:
  ScriptedSource(std::vector<core::RgbdFrame> frames, Script script)
      : frames_(std::move(frames)), script_(script) {}

  void Open() override {
    if (script_.opens != nullptr) script_.opens->fetch_add(1);
    if (pending_failures_ > 0) {
      --pending_failures_;
      throw std::runtime_error("scripted device not found");
    }
    open_ = true;
    opened_at_ = served_;
  }
  core::ReadStatus Read(int timeout_ms, core::RgbdFrame* frame) override {
    if (!open_) return core::ReadStatus::kError;
    if (script_.gate_after >= 0 && served_ == script_.gate_after) {
      std::unique_lock<std::mutex> lock(mutex_);
      if (!cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return gate_open_; })) {
        return core::ReadStatus::kTimeout;
      }
    }
    if (script_.period_us > 0)
      std::this_thread::sleep_for(std::chrono::microseconds(script_.period_us));
    if (script_.total_frames >= 0 && served_ >= script_.total_frames) {
      return core::ReadStatus::kEndOfStream;
    }
    if (served_ == script_.disconnect_after && !disconnected_) {
      disconnected_ = true;
      pending_failures_ = script_.failed_reopens;
      error_ = "scripted unplug";
      return core::ReadStatus::kDisconnected;
    }
    if (served_ == script_.error_after) {
      error_ = "scripted sensor fault";
      return core::ReadStatus::kError;
    }
    const core::RgbdFrame& src = frames_[static_cast<size_t>(served_) % frames_.size()];
    frame->utime = static_cast<int64_t>(served_) * 33333;
    frame->sequence =
        static_cast<uint64_t>(script_.sequence_from_open ? served_ - opened_at_ : served_);
    frame->intrinsics = src.intrinsics;
    frame->depth = src.depth;
    frame->color = src.color;
    ++served_;
    return core::ReadStatus::kOk;
  }
  void Close() override { open_ = false; }
  bool IsLive() const override { return script_.live; }
  std::string Describe() const override { return "scripted"; }
  std::string last_error() const override { return error_; }

  void OpenGate() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      gate_open_ = true;
    }
    cv_.notify_all();
  }

 private:
  std::vector<core::RgbdFrame> frames_;
  Script script_;
  int served_{0};
  int opened_at_{0};  // served_ at the last Open()
  bool open_{false};
  bool disconnected_{false};
  int pending_failures_{0};
  std::string error_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool gate_open_{false};
};

}  // namespace clutterseg::daemon::testutil
