#include "clutterseg/daemon/overlay_writer.h"

#include <pthread.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include <sys/resource.h>
#include <sys/syscall.h>

#include "clutterseg/core/param_check.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/daemon/realtime.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/pipeline/overlay.h"

namespace clutterseg::daemon {

void OverlayWriterParams::ValidateOrThrow() const {
  core::ParamCheck("output").InRange("queue_capacity", queue_capacity, 1, 1024);
}

OverlayWriter::OverlayWriter(const OverlayWriterParams& params)
    : params_((params.ValidateOrThrow(), params)),
      queue_(static_cast<size_t>(params.queue_capacity)) {}

OverlayWriter::~OverlayWriter() { Finish(); }

void OverlayWriter::Start() {
  std::error_code ec;
  std::filesystem::create_directories(params_.png_dir, ec);
  if (ec || !std::filesystem::is_directory(params_.png_dir)) {
    throw std::invalid_argument("output.png_dir '" + params_.png_dir +
                                "': cannot create the directory" +
                                (ec ? ": " + ec.message() : std::string()));
  }
  thread_ = std::thread([this] { Loop(); });
}

void OverlayWriter::Offer(OverlayFrame* frame, std::chrono::milliseconds wait_for_room) {
  queue_.Push(frame, wait_for_room);
}

void OverlayWriter::Finish(bool drop_waiting) {
  if (drop_waiting) {
    // The writer runs at the lowest priority: on a loaded machine each PNG can take it a
    // second or more, so a stop does not wait for what is queued (counted as dropped), and
    // the frame it has taken is dropped too unless its PNG is already being written.
    abandon_.store(true);
    queue_.CloseAndDropWaiting();
    // The frame it is rendering or encoding finishes at normal priority where that is allowed
    // (root, CAP_SYS_NICE, or RLIMIT_NICE: the systemd unit sets LimitNICE=+0); otherwise it
    // finishes at the lowest.
    if (const pid_t tid = tid_.load(); tid > 0) {
      setpriority(PRIO_PROCESS, static_cast<id_t>(tid), 0);
    }
  } else {
    queue_.Close();
  }
  if (thread_.joinable()) thread_.join();
}

std::string OverlayWriter::last_error() const {
  std::lock_guard<std::mutex> lock(error_mutex_);
  return last_error_;
}

void OverlayWriter::Loop() {
  pthread_setname_np(pthread_self(), "cs-overlay");
  // The lowest priority: PNGs take the CPU the segmentation leaves (a 30 Hz camera leaves a
  // third of a frame period); when there is none, the queue drops and counts overlays instead
  // of the lanes waiting for the encoder.
  // Never in a real-time class (processing.realtime_priority): there nice does not apply.
  if (std::string problem; ThreadIsRealtime() && !SetThreadRealtime(0, &problem)) {
    Log(LogLevel::kWarn, "overlay writer: cannot leave the real-time class: " + problem);
  }
  const auto tid = static_cast<pid_t>(syscall(SYS_gettid));
  setpriority(PRIO_PROCESS, static_cast<id_t>(tid), 19);
  tid_.store(tid);
  OverlayFrame frame;
  core::ColorImage image;
  io::PngWriter png;  // its buffers are reused from frame to frame
  for (;;) {
    if (!queue_.Pop(&frame, std::chrono::milliseconds(100))) {
      if (queue_.drained()) return;
      continue;
    }
    if (abandon_.load()) {
      abandoned_.fetch_add(1);
      continue;
    }
    char name[64];
    std::snprintf(name, sizeof(name), "/frame_%06llu.png",
                  static_cast<unsigned long long>(frame.sequence));
    const std::string path = params_.png_dir + name;
    try {
      pipeline::RenderOverlay(frame.labels, frame.base.empty() ? nullptr : &frame.base,
                              frame.objects, &image);
      if (abandon_.load()) {
        abandoned_.fetch_add(1);
        continue;
      }
      png.WriteColor(path, image);
      written_.fetch_add(1);
    } catch (const std::exception& e) {
      const uint64_t n = failures_.fetch_add(1) + 1;
      {
        std::lock_guard<std::mutex> lock(error_mutex_);
        last_error_ = e.what();
      }
      // The first failure and then one in a hundred: a full disk fails every frame.
      if (n == 1 || n % 100 == 0) {
        Log(LogLevel::kWarn,
            "overlay PNG not written (" + std::to_string(n) + " so far): " + e.what());
      }
    }
  }
}

}  // namespace clutterseg::daemon
