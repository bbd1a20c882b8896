#include "daemon/lcm_bus.h"

#include <lcm/lcm-cpp.hpp>

namespace clutterseg::daemon {

std::string MulticastRouteHelp() {
  return "LCM's udpm:// provider needs a multicast route. On Linux, for this machine only:\n"
         "    sudo ip link set lo multicast on\n"
         "    sudo ip route add 224.0.0.0/4 dev lo\n"
         "(or route 224.0.0.0/4 via the network interface that reaches the subscribers).\n"
         "Alternatively publish with --lcm-url memq:// (in-process) or "
         "--lcm-url 'file:///abs/path/out.lcmlog?mode=w' (write an LCM log).";
}

LcmBus::LcmBus(const std::string& url) : url_(url) {
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

LcmBus::~LcmBus() = default;

bool LcmBus::Publish(const std::string& channel, const void* data, size_t size) {
  if (size > static_cast<size_t>(INT32_MAX) ||
      lcm_->publish(channel, data, static_cast<unsigned int>(size)) != 0) {
    return CountFailure();
  }
  published_.fetch_add(1, std::memory_order_relaxed);
  return true;
}

bool LcmBus::CountFailure() {
  failures_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

}  // namespace clutterseg::daemon
