#include "clutterseg/daemon/lcm_bus.h"

#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include "clutterseg/daemon/lcm_log_file.h"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

clutterseg::objects_t Objects(int64_t seq, int num_objects) {
  clutterseg::objects_t m{};
  m.utime = seq * 1000;
  m.frame_seq = seq;
  m.camera_name = "camera";
  m.num_objects = num_objects;
  m.objects.resize(static_cast<size_t>(num_objects));
  for (int i = 0; i < num_objects; ++i) m.objects[static_cast<size_t>(i)].id = i + 1;
  return m;
}

struct Collector {
  std::vector<int64_t> seqs;
  std::vector<int> counts;
  void Handle(const lcm::ReceiveBuffer*, const std::string&, const clutterseg::objects_t* msg) {
    seqs.push_back(msg->frame_seq);
    counts.push_back(msg->num_objects);
  }
};

TEST(LcmBus, MemqDeliversToSubscribersOfTheSameInstance) {
  LcmBus dut("memq://");
  Collector got;
  dut.Subscribe<clutterseg::objects_t>(
      "CLUTTERSEG_OBJECTS",
      [&got](const clutterseg::objects_t& m) { got.Handle(nullptr, {}, &m); });
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(dut.PublishMessage("CLUTTERSEG_OBJECTS", Objects(i, i)));
  while (dut.Handle(0) > 0) {
  }
  EXPECT_EQ(got.seqs, (std::vector<int64_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(got.counts, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(dut.published(), 5u);
  EXPECT_EQ(dut.failures(), 0u);

  // A second memq instance is a different bus.
  LcmBus other("memq://");
  Collector none;
  other.Subscribe<clutterseg::objects_t>(
      "CLUTTERSEG_OBJECTS",
      [&none](const clutterseg::objects_t& m) { none.Handle(nullptr, {}, &m); });
  dut.PublishMessage("CLUTTERSEG_OBJECTS", Objects(9, 1));
  other.Handle(10);
  EXPECT_TRUE(none.seqs.empty());
}

// Subscriptions go through LCM's C API (no member-function handlers): the channel name is
// passed on, undecodable messages are counted, and a handler's exception comes out of Handle()
// instead of crossing LCM's C callback.
TEST(LcmBus, SubscribeDecodesCountsBadMessagesAndRethrowsHandlerErrors) {
  LcmBus dut("memq://");
  std::vector<std::string> channels;
  std::vector<int64_t> seqs;
  dut.Subscribe<clutterseg::objects_t>(
      "CLUTTERSEG_.*", [&](std::string_view channel, const clutterseg::objects_t& m) {
        channels.emplace_back(channel);
        seqs.push_back(m.frame_seq);
        if (m.frame_seq == 7) throw std::runtime_error("handler failed on frame 7");
      });
  std::vector<size_t> raw_sizes;
  dut.SubscribeRaw("CLUTTERSEG_A", [&](std::string_view, const uint8_t*, size_t size) {
    raw_sizes.push_back(size);
  });

  ASSERT_TRUE(dut.PublishMessage("CLUTTERSEG_A", Objects(3, 2)));
  const uint8_t garbage[5] = {1, 2, 3, 4, 5};
  ASSERT_TRUE(dut.Publish("CLUTTERSEG_B", garbage, sizeof(garbage)));
  ASSERT_TRUE(dut.PublishMessage("CLUTTERSEG_B", Objects(7, 1)));
  ASSERT_TRUE(dut.PublishMessage("OTHER", Objects(8, 1)));

  EXPECT_GT(dut.Handle(0), 0);
  EXPECT_GT(dut.Handle(0), 0);
  EXPECT_THROW(dut.Handle(0), std::runtime_error);
  // "OTHER" matches no subscription; the handler's error was reported once only.
  EXPECT_NO_THROW({
    while (dut.Handle(0) > 0) {
    }
  });
  EXPECT_EQ(channels, (std::vector<std::string>{"CLUTTERSEG_A", "CLUTTERSEG_B"}));
  EXPECT_EQ(seqs, (std::vector<int64_t>{3, 7}));
  EXPECT_EQ(raw_sizes.size(), 1u);
  EXPECT_EQ(dut.decode_failures(), 1u);
}

TEST(LcmBus, FileLogIsReadBackWithLogFile) {
  const auto path = testing::ScratchDir("lcm_bus_file") / "out.lcmlog";
  {
    LcmBus dut("file://" + path.string() + "?mode=w");
    for (int i = 0; i < 20; ++i) dut.PublishMessage("CLUTTERSEG_OBJECTS", Objects(i, 3));
    clutterseg::status_t s{};
    s.device_state_name = "streaming";
    dut.PublishMessage("CLUTTERSEG_STATUS", s);
    EXPECT_EQ(dut.published(), 21u);
  }
  const auto events = testutil::ReadLcmLog(path.string());
  ASSERT_EQ(events.size(), 21u);
  for (int i = 0; i < 20; ++i) {
    ASSERT_EQ(events[static_cast<size_t>(i)].channel, "CLUTTERSEG_OBJECTS");
    clutterseg::objects_t m;
    const auto& d = events[static_cast<size_t>(i)].data;
    ASSERT_EQ(m.decode(d.data(), 0, static_cast<int>(d.size())), static_cast<int>(d.size()));
    EXPECT_EQ(m.frame_seq, i);
    EXPECT_EQ(m.num_objects, 3);
  }
  EXPECT_EQ(events.back().channel, "CLUTTERSEG_STATUS");
}

// The log is read back while it is written (once a second), so that Verify() after a stop reads
// only the last second's events, however long the run: an appended log of earlier events and
// this run's events verify whole; damage in events already read back is found during the run,
// and damage in the rest by Verify().
TEST(LcmLogFile, ReadBackWhileWritingAndTheRestAtTheEnd) {
  const auto dir = testing::ScratchDir("lcm_log_readback");
  const std::string path = (dir / "out.lcmlog").string();
  const std::string payload(1000, 'x');
  {
    LcmLogFile earlier(FileLogUrl{path, false});
    for (int i = 0; i < 500; ++i) ASSERT_TRUE(earlier.Write("EARLIER", payload.data(), 100));
    EXPECT_EQ(earlier.Verify(), "");
  }
  const auto write_for_a_check = [&](LcmLogFile* log) {
    for (int i = 0; i < 50; ++i) ASSERT_TRUE(log->Write("CH", payload.data(), payload.size()));
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));   // past the check period
    ASSERT_TRUE(log->Write("CH", payload.data(), payload.size()));  // checks what is written
  };
  const auto corrupt = [&](uint64_t at) {
    const int fd = open(path.c_str(), O_WRONLY);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(pwrite(fd, "JUNK", 4, static_cast<off_t>(at)), 4);
    close(fd);
  };
  const uint64_t event_bytes = 28 + 2 + payload.size();
  {
    LcmLogFile log(FileLogUrl{path, true});
    EXPECT_EQ(log.events_before(), 500u);
    write_for_a_check(&log);
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(log.Write("CH", payload.data(), payload.size()));
    EXPECT_EQ(log.written(), 61u);
    EXPECT_EQ(log.Verify(), "");
    // A sync word overwritten in the last ten events (not read back yet): found by Verify.
    const uint64_t size = std::filesystem::file_size(path);
    corrupt(size - 3 * event_bytes);
    const std::string problem = log.Verify();
    EXPECT_NE(problem.find("is cut short"), std::string::npos) << problem;
    EXPECT_NE(problem.find("no sync word at byte " + std::to_string(size - 3 * event_bytes)),
              std::string::npos)
        << problem;
  }
  {
    LcmLogFile log(FileLogUrl{path, false});
    for (int i = 0; i < 20; ++i) ASSERT_TRUE(log.Write("CH", payload.data(), payload.size()));
    corrupt(5 * event_bytes);  // damage before the next check: the check finds it
    write_for_a_check(&log);
    const std::string problem = log.Verify();
    EXPECT_NE(problem.find("no sync word at byte " + std::to_string(5 * event_bytes) +
                           " (read back while writing)"),
              std::string::npos)
        << problem;
  }
}

// A FIFO named as a log to read used to block liblcm's open until a writer came
// (clutterseg-listen hung): refused at once, naming it, as for a log that is written.
TEST(LcmBus, AFifoAsALogToReadIsRefusedWithoutBlocking) {
  const auto dir = testing::ScratchDir("lcm_bus_fifo");
  const std::string fifo = (dir / "log.fifo").string();
  std::filesystem::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& url : {"file://" + fifo + "?speed=0", "file://" + fifo}) {
    try {
      LcmBus dut(url);
      ADD_FAILURE() << url << " was opened";
    } catch (const LcmUnavailableError& e) {
      EXPECT_NE(std::string(e.what()).find(fifo + " is not a regular file"), std::string::npos)
          << e.what();
    }
  }
}

TEST(LcmBus, UnopenableUrlsThrowWithAClearMessage) {
  try {
    LcmBus dut("file:///nonexistent_dir_for_clutterseg/x.lcmlog?mode=r");
    FAIL() << "expected LcmUnavailableError";
  } catch (const LcmUnavailableError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("nonexistent_dir_for_clutterseg"), std::string::npos) << msg;
    EXPECT_NE(msg.find("log file"), std::string::npos) << msg;
  }
  try {
    LcmBus dut("bogus://x");
    FAIL() << "expected LcmUnavailableError";
  } catch (const LcmUnavailableError& e) {
    EXPECT_NE(std::string(e.what()).find("bogus://x"), std::string::npos) << e.what();
  }
}

TEST(LcmBus, MulticastHelpNamesTheRouteCommand) {
  const std::string help = MulticastRouteHelp();
  EXPECT_NE(help.find("ip route add 224.0.0.0/4 dev lo"), std::string::npos);
  EXPECT_NE(help.find("memq://"), std::string::npos);
}

TEST(LcmBus, FailedPublishesAreCounted) {
  // tcpq:// reports good() even without a hub, then every publish fails. Point it at a
  // loopback port that was just closed, so nothing can be listening.
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(s, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(s, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  socklen_t len = sizeof(addr);
  ASSERT_EQ(getsockname(s, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  const int port = ntohs(addr.sin_port);
  close(s);
  LcmBus dut("tcpq://127.0.0.1:" + std::to_string(port));
  EXPECT_FALSE(dut.PublishMessage("CLUTTERSEG_OBJECTS", Objects(0, 1)));
  EXPECT_FALSE(dut.PublishMessage("CLUTTERSEG_OBJECTS", Objects(1, 1)));
  EXPECT_EQ(dut.failures(), 2u);
  EXPECT_EQ(dut.published(), 0u);
}

TEST(LcmBus, UdpmBetweenTwoProcessesInAPrivateNamespace) {
  testutil::NetNamespace ns(/*route=*/true);
  if (!ns.ok()) GTEST_SKIP() << "udpm test skipped: " << ns.why();
  const std::string url = "udpm://239.255.76.67:7667?ttl=0";
  const auto ready = testing::ScratchDir("lcm_udpm") / "ready";
  testutil::Child sub = testutil::Spawn(ns.Exec(
      {LCM_UDPM_PEER, "sub", url + "&recv_buf_size=4194304", "CS_TEST", "40", ready.string()}));
  ASSERT_GT(sub.pid, 0);
  for (int i = 0; i < 1000 && !std::filesystem::exists(ready); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(std::filesystem::exists(ready)) << "the subscriber did not start";
  std::string pub_err;
  const int pub_rc = testutil::Run(ns.Exec({LCM_UDPM_PEER, "pub", url, "CS_TEST", "40"}),
                                   std::chrono::seconds(30), &pub_err);
  EXPECT_EQ(pub_rc, 0) << pub_err;
  std::string sub_err;
  EXPECT_EQ(testutil::Wait(&sub, std::chrono::seconds(30), &sub_err), 0) << sub_err;
  EXPECT_NE(sub_err.find("received 40 in_order 1"), std::string::npos) << sub_err;
}

}  // namespace
}  // namespace clutterseg::daemon
