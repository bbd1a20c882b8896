#include "clutterseg/daemon/lcm_publisher.h"

#include <pthread.h>

#include <chrono>
#include <iterator>
#include <utility>

#include "clutterseg/core/frame.h"
#include "clutterseg/core/param_check.h"
#include "clutterseg/daemon/log.h"

namespace clutterseg::daemon {

namespace {

// LCM's limit on channel names (LCM_MAX_CHANNEL_NAME_LENGTH): longer names are refused by
// every provider at publish time.
constexpr size_t kMaxChannelBytes = 63;

bool IsChannelName(const std::string& name) {
  if (name.empty() || name.size() > kMaxChannelBytes) return false;
  for (const char c : name) {
    if (c <= ' ' || c > '~') return false;  // printable ASCII without spaces
  }
  return true;
}

}  // namespace

void LcmPublisherParams::ValidateOrThrow() const {
  const core::ParamCheck check("lcm");
  const std::pair<const char*, const std::string*> channels[] = {
      {"objects_channel", &objects_channel},
      {"labels_channel", &labels_channel},
      {"status_channel", &status_channel},
      {"depth_channel", &depth_channel}};
  for (size_t i = 0; i < std::size(channels); ++i) {
    const auto& [key, name] = channels[i];
    if (!IsChannelName(*name)) {
      check.Fail(key, "'" + *name + "'",
                 "a channel name of 1 to 63 printable ASCII characters without spaces (LCM's "
                 "limit)");
    }
    for (size_t j = 0; j < i; ++j) {
      if (*channels[j].second == *name) {
        check.Fail(key, "'" + *name + "'",
                   std::string("a channel other than lcm.") + channels[j].first +
                       " (each message type needs its own channel)");
      }
    }
  }
  check.InRange("object_points", object_points, 0, 100000);
  check.InRange("queue_capacity", queue_capacity, 1, 1024);
}

LcmPublisher::LcmPublisher(const LcmPublisherParams& params, LcmBus* bus, OnPublished on_published)
    : params_((params.ValidateOrThrow(), params)),
      bus_(bus),
      on_published_(std::move(on_published)),
      queue_(static_cast<size_t>(params.queue_capacity)) {}

LcmPublisher::~LcmPublisher() { Finish(); }

void LcmPublisher::Start() {
  thread_ = std::thread([this] { Loop(); });
}

void LcmPublisher::Offer(FrameMessages* frame, std::chrono::milliseconds wait_for_room) {
  if (!queue_.Push(frame,
                   wait_for_room)) {  // after Finish: count it as handled so Flush does not wait
    std::lock_guard<std::mutex> lock(flush_mutex_);
    ++handled_;
  }
}

void LcmPublisher::OfferStatus(const clutterseg::status_t& status) {
  std::lock_guard<std::mutex> lock(status_mutex_);
  pending_status_ = status;
  status_pending_ = true;
}

void LcmPublisher::Flush() {
  std::unique_lock<std::mutex> lock(flush_mutex_);
  flush_cv_.wait(lock, [&] { return handled_ + queue_.dropped() >= queue_.pushed(); });
}

void LcmPublisher::Finish() {
  queue_.Close();
  if (thread_.joinable()) thread_.join();
}

void LcmPublisher::PublishPendingStatus() {
  clutterseg::status_t status;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    if (!status_pending_) return;
    std::swap(status, pending_status_);
    status_pending_ = false;
  }
  bus_->PublishMessage(params_.status_channel, status);
}

void LcmPublisher::Loop() {
  pthread_setname_np(pthread_self(), "cs-publish");
  FrameMessages frame;
  for (;;) {
    const bool got = queue_.Pop(&frame, std::chrono::milliseconds(20));
    if (got) {
      try {
        const int64_t now_us = core::SteadyClockMicros();
        frame.objects.capture_to_publish_ms =
            static_cast<float>(static_cast<double>(now_us - frame.receive_utime) * 1e-3);
        const bool ok = bus_->PublishMessage(params_.objects_channel, frame.objects);
        if (frame.has_labels) bus_->PublishMessage(params_.labels_channel, frame.labels);
        if (frame.has_depth) bus_->PublishMessage(params_.depth_channel, frame.depth);
        (ok ? frames_published_ : frames_failed_).fetch_add(1);
        if (on_published_) on_published_(frame, ok);
      } catch (const std::exception& e) {
        frames_failed_.fetch_add(1);
        Log(LogLevel::kError, std::string("publishing failed: ") + e.what());
      }
      {
        std::lock_guard<std::mutex> lock(flush_mutex_);
        ++handled_;
      }
      flush_cv_.notify_all();
    }
    try {
      PublishPendingStatus();
    } catch (const std::exception& e) {
      Log(LogLevel::kError, std::string("publishing the status failed: ") + e.what());
    }
    if (!got && queue_.drained()) break;
  }
  flush_cv_.notify_all();
}

}  // namespace clutterseg::daemon
