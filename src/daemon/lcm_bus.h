#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace lcm {
class LCM;
}  // namespace lcm

namespace clutterseg::daemon {

class LcmLogFile;

/// The LCM URL could not be opened (most often: udpm:// without a multicast route). The
/// message says how to fix it.
class LcmUnavailableError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// How to give a Linux machine a multicast route for udpm://, for error messages.
std::string MulticastRouteHelp();

/// Owns one lcm::LCM instance and publishes on it, counting failures instead of ignoring
/// them (publish() returning -1, e.g. tcpq:// without a hub, or an encoding error). Also
/// receives: Subscribe() registers handlers that Handle() (or lcm()->handle*()) dispatches.
///
/// A file:// URL that writes a log (?mode=w or ?mode=a) is not opened through LCM: the bus
/// writes the log itself (LcmLogFile), so that a message counts as published only once it is
/// in the file, and one the file system refuses (a full disk) counts as a failure. Such a bus
/// publishes only: it has no lcm::LCM instance, Subscribe() throws and Handle() returns -1.
///
/// Subscribe() goes through LCM's C API with a plain function callback. LCM's C++
/// member-function subscriptions (lcm::LCM::subscribe(channel, &Class::Method, object)) are
/// valid C++ but make GCC's UndefinedBehaviorSanitizer abort the ASan+UBSan build with a false
/// "member access within null pointer" report inside lcm-cpp-impl.hpp; use Subscribe().
///
/// Thread-safety: Publish and PublishMessage from one thread at a time (the daemon's
/// publisher thread); Subscribe and Handle from one (receiving) thread at a time; the
/// counters may be read from any thread.
class LcmBus {
 public:
  LcmBus(const LcmBus&) = delete;
  LcmBus& operator=(const LcmBus&) = delete;

  /// Opens `url` ("" = LCM's default, udpm://239.255.76.67:7667?ttl=0).
  /// @throws LcmUnavailableError naming the URL, with the multicast route fix for udpm, or the
  /// log file and what is wrong with it (LcmLogFile) for a file:// log.
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

  /// Handler of raw messages: the channel and the encoded bytes (valid during the call only).
  using RawHandler =
      std::function<void(std::string_view channel, const uint8_t* data, size_t size)>;

  /// Receives every message of `channel` (an LCM channel regular expression, e.g. "FOO" or
  /// "CLUTTERSEG_.*") as `handler(channel, data, size)`. Handlers run on the thread that calls
  /// Handle(). A handler should not throw: an exception is caught (it must not cross LCM's C
  /// callback), kept, and rethrown by the next Handle().
  /// @throws std::invalid_argument for an empty handler, std::runtime_error when LCM refuses.
  void SubscribeRaw(const std::string& channel, RawHandler handler);

  /// Receives every message of `channel` decoded as the lcm-gen type `Message` (decoded into
  /// one instance reused across messages) and calls `handler(message)` or
  /// `handler(channel, message)` with `const Message&`. Messages that do not decode are
  /// skipped and counted in decode_failures().
  template <typename Message, typename Handler>
  void Subscribe(const std::string& channel, Handler handler) {
    static_assert(std::is_invocable_v<Handler&, const Message&> ||
                      std::is_invocable_v<Handler&, std::string_view, const Message&>,
                  "handler must take (const Message&) or (std::string_view, const Message&)");
    SubscribeRaw(channel, [this, handler = std::move(handler), message = Message()](
                              std::string_view name, const uint8_t* data, size_t size) mutable {
      if (size > static_cast<size_t>(INT32_MAX) ||
          message.decode(data, 0, static_cast<int>(size)) < 0) {
        decode_failures_.fetch_add(1, std::memory_order_relaxed);
        return;
      }
      if constexpr (std::is_invocable_v<Handler&, const Message&>) {
        handler(static_cast<const Message&>(message));
      } else {
        handler(name, static_cast<const Message&>(message));
      }
    });
  }

  /// Waits up to `timeout_ms` (>= 0) for a message and dispatches it to the subscribed
  /// handlers. Returns > 0 when a message was handled, 0 on timeout, < 0 on an LCM error or at
  /// the end of a file:// log (LCM's handleTimeout() convention).
  /// @throws the exception a handler threw since the last call (the message is consumed).
  int Handle(int timeout_ms);

  /// Messages published successfully.
  uint64_t published() const { return published_.load(std::memory_order_relaxed); }
  /// Publish calls that failed.
  uint64_t failures() const { return failures_.load(std::memory_order_relaxed); }
  /// Received messages that Subscribe() could not decode as the subscribed type.
  uint64_t decode_failures() const { return decode_failures_.load(std::memory_order_relaxed); }
  const std::string& url() const { return url_; }
  /// The underlying instance, e.g. to handle messages on the same memq:// bus in tests;
  /// nullptr for a file:// log the bus writes itself.
  lcm::LCM* lcm() { return lcm_.get(); }
  /// The file:// log the bus writes, nullptr for any other URL.
  const LcmLogFile* log_file() const { return log_file_.get(); }

 private:
  struct Subscription;

  bool CountFailure();

  std::string url_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::unique_ptr<LcmLogFile> log_file_;  // instead of lcm_ for a file:// log
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  std::exception_ptr handler_error_;  // first exception a handler threw, for Handle()
  std::vector<uint8_t> buffer_;
  std::atomic<uint64_t> published_{0};
  std::atomic<uint64_t> failures_{0};
  std::atomic<uint64_t> decode_failures_{0};
};

}  // namespace clutterseg::daemon
