#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace lcm {
class LCM;
}  // namespace lcm

namespace clutterseg::daemon {

/// The LCM URL could not be opened (most often: udpm:// without a multicast route). The
/// message says how to fix it.
class LcmUnavailableError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// How to give a Linux machine a multicast route for udpm://, for error messages.
std::string MulticastRouteHelp();

/// Owns one lcm::LCM instance and publishes on it, counting failures instead of ignoring
/// them (publish() returning -1, e.g. tcpq:// without a hub, or an encoding error).
///
/// Thread-safety: Publish and PublishMessage from one thread at a time (the daemon's
/// publisher thread); the counters may be read from any thread.
class LcmBus {
 public:
  LcmBus(const LcmBus&) = delete;
  LcmBus& operator=(const LcmBus&) = delete;

  /// Opens `url` ("" = LCM's default, udpm://239.255.76.67:7667?ttl=0).
  /// @throws LcmUnavailableError naming the URL, with the multicast route fix for udpm.
  explicit LcmBus(const std::string& url);
  ~LcmBus();

  /// Publishes raw bytes; returns false (and counts a failure) when LCM refuses them.
  bool Publish(const std::string& channel, const void* data, size_t size);

  /// Encodes an lcm-gen message into a reused buffer and publishes it.
  template <typename Message>
  bool PublishMessage(const std::string& channel, const Message& message) {
    const int size = message.getEncodedSize();
    if (size < 0) return CountFailure();
    buffer_.resize(static_cast<size_t>(size));
    if (message.encode(buffer_.data(), 0, size) != size) return CountFailure();
    return Publish(channel, buffer_.data(), buffer_.size());
  }

  /// Messages published successfully.
  uint64_t published() const { return published_.load(std::memory_order_relaxed); }
  /// Publish calls that failed.
  uint64_t failures() const { return failures_.load(std::memory_order_relaxed); }
  const std::string& url() const { return url_; }
  /// The underlying instance, e.g. to subscribe on the same memq:// bus in tests.
  lcm::LCM* lcm() { return lcm_.get(); }

 private:
  bool CountFailure();

  std::string url_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::vector<uint8_t> buffer_;
  std::atomic<uint64_t> published_{0};
  std::atomic<uint64_t> failures_{0};
};

}  // namespace clutterseg::daemon
