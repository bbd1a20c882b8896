// Helper process for the udpm test (run inside a private network namespace):
//   lcm_udpm_peer pub URL CHANNEL N          publishes objects_t frame_seq 0..N-1 via LcmBus
//   lcm_udpm_peer sub URL CHANNEL N READY    creates file READY once subscribed, then exits 0
//                                            after N distinct in-order messages (1 on timeout)
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include <lcm/lcm-cpp.hpp>

#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/objects_t.hpp"

namespace {

int Publish(const std::string& url, const std::string& channel, int n) {
  try {
    clutterseg::daemon::LcmBus bus(url);
    clutterseg::objects_t msg{};
    msg.camera_name = "camera";
    for (int i = 0; i < n; ++i) {
      msg.frame_seq = i;
      msg.utime = i * 33333;
      msg.num_objects = 1;
      msg.objects.resize(1);
      msg.objects[0].id = 1;
      msg.objects[0].centroid[2] = 0.5f + 0.01f * static_cast<float>(i);
      if (!bus.PublishMessage(channel, msg)) return 2;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return bus.failures() == 0 ? 0 : 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 4;
  }
}

struct Counter {
  int received{0};
  int64_t next{0};
  bool in_order{true};
  void Handle(const lcm::ReceiveBuffer*, const std::string&, const clutterseg::objects_t* msg) {
    if (msg->frame_seq < next) in_order = false;
    next = msg->frame_seq + 1;
    ++received;
  }
};

int Subscribe(const std::string& url, const std::string& channel, int n, const std::string& ready) {
  std::unique_ptr<clutterseg::daemon::LcmBus> bus;
  try {
    bus = std::make_unique<clutterseg::daemon::LcmBus>(url);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "subscriber: LCM not good: %s\n", e.what());
    return 4;
  }
  Counter counter;
  bus->Subscribe<clutterseg::objects_t>(
      channel, [&counter](const clutterseg::objects_t& m) { counter.Handle(nullptr, {}, &m); });
  // The udpm self-test runs on the first handle: do one before declaring readiness.
  bus->Handle(10);
  std::ofstream(ready) << "ready\n";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (counter.received < n && std::chrono::steady_clock::now() < deadline) {
    bus->Handle(100);
  }
  std::fprintf(stderr, "received %d in_order %d\n", counter.received, counter.in_order ? 1 : 0);
  return counter.received == n && counter.in_order ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 5 && std::string(argv[1]) == "pub")
    return Publish(argv[2], argv[3], std::atoi(argv[4]));
  if (argc >= 6 && std::string(argv[1]) == "sub") {
    return Subscribe(argv[2], argv[3], std::atoi(argv[4]), argv[5]);
  }
  std::fprintf(stderr, "usage: lcm_udpm_peer pub URL CHANNEL N | sub URL CHANNEL N READY_FILE\n");
  return 2;
}
