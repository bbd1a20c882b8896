#include "clutterseg/daemon/lcm_bus.h"

#include <exception>
#include <stdexcept>
#include <utility>

#include <lcm/lcm-cpp.hpp>
#include <lcm/lcm.h>

#include "clutterseg/core/file_kind.h"
#include "clutterseg/daemon/lcm_log_file.h"

namespace clutterseg::daemon {

// One SubscribeRaw() registration: LCM's C API calls OnMessage with it as user data.
struct LcmBus::Subscription {
  LcmBus* bus{nullptr};
  RawHandler handler;
  lcm_subscription_t* c_subscription{nullptr};

  static void OnMessage(const lcm_recv_buf_t* rbuf, const char* channel, void* user) noexcept {
    auto* self = static_cast<Subscription*>(user);
    try {
      self->handler(channel != nullptr ? std::string_view(channel) : std::string_view(),
                    static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
    } catch (...) {  // nothing may escape into LCM's C code
      if (!self->bus->handler_error_) self->bus->handler_error_ = std::current_exception();
    }
  }
};

std::string MulticastRouteHelp() {
  return "LCM's udpm:// provider needs a multicast route. On Linux, for this machine only:\n"
         "    sudo ip link set lo multicast on\n"
         "    sudo ip route add 224.0.0.0/4 dev lo\n"
         "(or route 224.0.0.0/4 via the network interface that reaches the subscribers).\n"
         "Alternatively publish with --lcm-url memq:// (in-process) or "
         "--lcm-url 'file:///abs/path/out.lcmlog?mode=w' (write an LCM log).";
}

LcmBus::LcmBus(const std::string& url) : url_(url) {
  if (FileLogUrl log; ParseFileLogUrl(url, &log)) {
    try {
      log_file_ = std::make_unique<LcmLogFile>(log);
    } catch (const std::exception& e) {
      throw LcmUnavailableError("cannot open LCM URL '" + url + "': " + e.what());
    }
    return;
  }
  // A log to read: liblcm's fopen() of a FIFO would wait for a writer, and a directory or
  // device is no log; refused before LCM opens it.
  if (const std::string path = FileUrlPath(url); !path.empty() && core::IsNonRegularFile(path)) {
    throw LcmUnavailableError("cannot open LCM URL '" + url + "': " + path +
                              " is not a regular file (a FIFO, device or directory); LCM "
                              "reads logs from regular files");
  }
  lcm_ = std::make_unique<lcm::LCM>(url);
  if (!lcm_->good()) {
    lcm_.reset();
    const std::string shown = url.empty() ? "(default) udpm://239.255.76.67:7667?ttl=0" : url;
    std::string message = "cannot open LCM URL '" + shown + "'";
    if (url.empty() || url.rfind("udpm", 0) == 0 || url.rfind("mpudpm", 0) == 0) {
      message += ".\n" + MulticastRouteHelp();
    } else if (url.rfind("file://", 0) == 0) {
      message +=
          ": the log file cannot be opened (check the path, its directory and ?mode=w "
          "for writing)";
    } else {
      message += ": LCM rejected the URL (supported providers: udpm, mpudpm, memq, file, tcpq)";
    }
    throw LcmUnavailableError(message);
  }
}

LcmBus::~LcmBus() {
  if (lcm_) {
    for (const auto& s : subscriptions_) {
      if (s->c_subscription != nullptr) {
        lcm_unsubscribe(lcm_->getUnderlyingLCM(), s->c_subscription);
      }
    }
  }
  subscriptions_.clear();
  lcm_.reset();
}

void LcmBus::SubscribeRaw(const std::string& channel, RawHandler handler) {
  if (!handler) throw std::invalid_argument("LcmBus::SubscribeRaw: empty handler for " + channel);
  if (!lcm_) {
    throw std::runtime_error("cannot subscribe to LCM channel '" + channel + "' on '" + url_ +
                             "': this process writes that log");
  }
  auto s = std::make_unique<Subscription>();
  s->bus = this;
  s->handler = std::move(handler);
  s->c_subscription =
      lcm_subscribe(lcm_->getUnderlyingLCM(), channel.c_str(), &Subscription::OnMessage, s.get());
  if (s->c_subscription == nullptr) {
    throw std::runtime_error("cannot subscribe to LCM channel '" + channel + "' on '" + url_ + "'");
  }
  subscriptions_.push_back(std::move(s));
}

int LcmBus::Handle(int timeout_ms) {
  if (!lcm_) return -1;  // a log this process writes: nothing to receive
  const int rc = lcm_->handleTimeout(timeout_ms < 0 ? 0 : timeout_ms);
  if (handler_error_) {
    std::exception_ptr error = std::exchange(handler_error_, nullptr);
    std::rethrow_exception(error);
  }
  return rc;
}

bool LcmBus::Publish(const std::string& channel, const void* data, size_t size) {
  if (size > static_cast<size_t>(INT32_MAX)) return CountFailure();
  const bool ok = log_file_ ? log_file_->Write(channel, data, size)
                            : lcm_->publish(channel, data, static_cast<unsigned int>(size)) == 0;
  if (!ok) return CountFailure();
  published_.fetch_add(1, std::memory_order_relaxed);
  return true;
}

bool LcmBus::CountFailure() {
  failures_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

}  // namespace clutterseg::daemon
