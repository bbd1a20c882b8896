// End-to-end tests of the `clutterseg` executable: exit codes, signals and LCM logs.
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>

#include "clutterseg/daemon/daemon.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

using std::chrono::seconds;

template <typename T>
bool Decode(const testutil::LogEvent& ev, T* msg) {
  return msg->decode(ev.data.data(), 0, static_cast<int>(ev.data.size())) ==
         static_cast<int>(ev.data.size());
}

class DaemonProcess : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    oni_path_ =
        (testing::ScratchDir("daemon_process_oni_" + std::to_string(getpid())) / "mosd5.oni")
            .string();
    have_oni_ = testutil::WriteMosdOni(oni_path_, kFrames);
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    std::filesystem::remove_all(std::filesystem::path(oni_path_).parent_path(), ec);
  }
  static constexpr int kFrames = 5;
  static inline std::string oni_path_;
  static inline bool have_oni_{false};
};

TEST_F(DaemonProcess, OniRecordingToFileLogOneObjectsPerFrame) {
  if (!have_oni_) GTEST_SKIP() << "shared data 'mosd-learn' not found under " << testing::DataDir();
  const auto log = testing::ScratchDir("daemon_process_log") / "out.lcmlog";
  std::string err;
  const int rc = testutil::Run({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "max",
                                "--lcm-url", "file://" + log.string() + "?mode=w"},
                               std::chrono::minutes(5), &err);
  ASSERT_EQ(rc, 0) << err;
  const auto events = testutil::ReadLcmLog(log.string());
  std::vector<int64_t> seqs;
  int labels = 0;
  int status = 0;
  clutterseg::status_t last_status;
  for (const auto& ev : events) {
    if (ev.channel == "CLUTTERSEG_OBJECTS") {
      clutterseg::objects_t m;
      ASSERT_TRUE(Decode(ev, &m));
      seqs.push_back(m.frame_seq);
    } else if (ev.channel == "CLUTTERSEG_LABELS") {
      clutterseg::label_image_t m;
      ASSERT_TRUE(Decode(ev, &m));
      EXPECT_EQ(m.compression, clutterseg::label_image_t::COMPRESSION_RLE);  // the default
      ++labels;
    } else if (ev.channel == "CLUTTERSEG_STATUS") {
      ASSERT_TRUE(Decode(ev, &last_status));
      ++status;
    } else {
      ADD_FAILURE() << "unexpected channel " << ev.channel;
    }
  }
  EXPECT_EQ(seqs, (std::vector<int64_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(labels, kFrames);
  ASSERT_GE(status, 1);
  EXPECT_EQ(last_status.device_state_name, "end_of_stream");
  EXPECT_EQ(last_status.frames_processed, kFrames);
  EXPECT_NE(err.find("fps"), std::string::npos) << "a status line on stderr: " << err;
}

TEST_F(DaemonProcess, SigtermFinishesInFlightFramesAndExitsZero) {
  if (!have_oni_) GTEST_SKIP() << "shared data 'mosd-learn' not found under " << testing::DataDir();
  const auto log = testing::ScratchDir("daemon_process_sigterm") / "out.lcmlog";
  testutil::Child child =
      testutil::Spawn({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "max", "--loop",
                       "--lcm-url", "file://" + log.string() + "?mode=w"});
  ASSERT_GT(child.pid, 0);
  // Wait until frames are flowing (the log grows), then ask it to stop.
  for (int i = 0; i < 3000; ++i) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(log, ec);
    if (!ec && size > 200000) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  std::string err;
  const int rc = testutil::Wait(&child, seconds(30), &err);
  const double stop_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(rc, 0) << err;
  std::printf("SIGTERM to exit: %.3f s\n", stop_s);
  int objects = 0;
  int64_t last_seq = -1;
  for (const auto& ev : testutil::ReadLcmLog(log.string())) {
    if (ev.channel != "CLUTTERSEG_OBJECTS") continue;
    clutterseg::objects_t m;
    ASSERT_TRUE(Decode(ev, &m));
    ++objects;
    last_seq = m.frame_seq;
  }
  EXPECT_GT(objects, 0);
  EXPECT_GE(last_seq, 0);
}

TEST(DaemonProcessConfig, BadConfigExitsTwoNamingTheKey) {
  const auto path = testing::ScratchDir("daemon_process_badcfg") / "bad.yaml";
  std::ofstream(path) << "lcm:\n  url: memq://\nsegmenter:\n  planes:\n    max_plane: 3\n";
  std::string err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_DAEMON_EXE, "--config", path.string()}, seconds(60), &err),
            kExitUsage);
  EXPECT_NE(err.find("segmenter.planes.max_plane"), std::string::npos) << err;
  EXPECT_NE(err.find(path.string()), std::string::npos) << err;

  err.clear();
  EXPECT_EQ(testutil::Run({CLUTTERSEG_DAEMON_EXE, "--speed", "warp"}, seconds(60), &err),
            kExitUsage);
  EXPECT_NE(err.find("speed"), std::string::npos) << err;
  EXPECT_NE(err.find("warp"), std::string::npos) << err;

  err.clear();
  EXPECT_EQ(testutil::Run({CLUTTERSEG_DAEMON_EXE, "--no-such-flag"}, seconds(60), &err),
            kExitUsage);
}

TEST(DaemonProcessConfig, MissingSourceExitsThree) {
  std::string err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_DAEMON_EXE, "--source", "/nonexistent/clutterseg.oni",
                           "--lcm-url", "memq://"},
                          seconds(60), &err),
            kExitSourceUnavailable);
  EXPECT_NE(err.find("/nonexistent/clutterseg.oni"), std::string::npos) << err;
}

TEST_F(DaemonProcess, UnroutableMulticastExitsFourWithTheFix) {
  if (!have_oni_) GTEST_SKIP() << "shared data 'mosd-learn' not found under " << testing::DataDir();
  testutil::NetNamespace ns(/*route=*/false);  // lo down, no multicast route
  if (!ns.ok()) GTEST_SKIP() << "skipped: " << ns.why();
  std::string err;
  const int rc = testutil::Run(ns.Exec({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--lcm-url",
                                        "udpm://239.255.76.67:7667?ttl=0"}),
                               seconds(60), &err);
  EXPECT_EQ(rc, kExitLcmUnavailable) << err;
  EXPECT_NE(err.find("ip route add 224.0.0.0/4 dev lo"), std::string::npos) << err;
}

TEST_F(DaemonProcess, PublishesOverUdpmInAPrivateNamespace) {
  if (!have_oni_) GTEST_SKIP() << "shared data 'mosd-learn' not found under " << testing::DataDir();
  testutil::NetNamespace ns(/*route=*/true);
  if (!ns.ok()) GTEST_SKIP() << "skipped: " << ns.why();
  const std::string url = "udpm://239.255.76.67:7667?ttl=0";
  const auto ready = testing::ScratchDir("daemon_process_udpm") / "ready";
  testutil::Child sub =
      testutil::Spawn(ns.Exec({LCM_UDPM_PEER, "sub", url + "&recv_buf_size=4194304",
                               "CLUTTERSEG_OBJECTS", std::to_string(kFrames), ready.string()}));
  ASSERT_GT(sub.pid, 0);
  for (int i = 0; i < 1000 && !std::filesystem::exists(ready); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(std::filesystem::exists(ready));
  std::string err;
  // Lockstep replay: every frame is published however slow the build (at the recorded speed a
  // sanitizer build drops frames like a live camera would).
  EXPECT_EQ(testutil::Run(ns.Exec({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "max",
                                   "--lcm-url", url}),
                          std::chrono::minutes(5), &err),
            0)
      << err;
  std::string sub_err;
  EXPECT_EQ(testutil::Wait(&sub, seconds(60), &sub_err), 0) << sub_err;
  EXPECT_NE(sub_err.find("received " + std::to_string(kFrames)), std::string::npos) << sub_err;
}

}  // namespace
}  // namespace clutterseg::daemon
