// Cameras on several machines of one LAN, as real network namespaces: two hosts each run a
// daemon of their own camera that publishes over udpm with ttl=1 through a bridge (an
// unmanaged switch), and a subscriber on a third host must receive every message of both,
// none twice. The deployment docs/daemon.md describes ("Cameras on several machines").
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_cli.h"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

using std::chrono::seconds;

constexpr char kGroup[] = "239.255.76.67";
constexpr char kLanUrl[] = "udpm://239.255.76.67:7667?ttl=1";

// What one camera's daemon delivered to the subscriber.
struct Received {
  std::set<int64_t> object_seqs;
  int objects{0};
  int labels{0};
  int statuses{0};
};

TEST(DaemonLan, TwoHostsPublishAndASubscriberOnAThirdReceivesEverything) {
  testutil::LanSegment lan(3);
  if (!lan.ok()) GTEST_SKIP() << "skipped: " << lan.why();
  const std::filesystem::path dir = testing::ScratchDir("daemon_lan");
  const std::string oni = (dir / "tabletop.oni").string();
  testutil::WriteTabletopOni(oni, 45);
  const std::string log = (dir / "subscriber.lcmlog").string();

  // The subscriber (host 2) first, certain to hear the group before anything is sent.
  testutil::Child logger = testutil::Spawn(
      lan.host(2).Exec({"lcm-logger", std::string("--lcm-url=") + kLanUrl, "-f", log}));
  ASSERT_GT(logger.pid, 0);
  ASSERT_TRUE(testutil::WaitForMulticastMember(lan.host(2), kGroup, seconds(20)))
      << "the subscriber never joined " << kGroup;

  const std::vector<std::string> cameras = {"left", "right"};
  std::vector<testutil::Child> daemons;
  for (size_t i = 0; i < cameras.size(); ++i) {
    daemons.push_back(testutil::Spawn(lan.host(static_cast<int>(i)).Exec(
        {CLUTTERSEG_DAEMON_EXE, "--source", oni, "--speed", "realtime", "--lcm-url", kLanUrl,
         "--set", "camera_name=" + cameras[i], "--set",
         "lcm.lock_dir=" + (dir / ("locks_" + cameras[i])).string()})));
    ASSERT_GT(daemons.back().pid, 0);
  }
  std::map<std::string, int64_t> published;
  for (size_t i = 0; i < cameras.size(); ++i) {
    std::string err;
    ASSERT_EQ(testutil::Wait(&daemons[i], seconds(120), &err), kExitOk) << cameras[i] << ":\n"
                                                                         << err;
    published[cameras[i]] = testutil::DoneCount(err, "published");
    ASSERT_GT(published[cameras[i]], 0) << err;
  }
  ASSERT_EQ(kill(logger.pid, SIGINT), 0);
  std::string logger_err;
  EXPECT_EQ(testutil::Wait(&logger, seconds(20), &logger_err), 0) << logger_err;

  std::map<std::string, Received> got;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
    const int n = static_cast<int>(ev.data.size());
    if (ev.channel == "CLUTTERSEG_OBJECTS") {
      clutterseg::objects_t o;
      ASSERT_GE(o.decode(ev.data.data(), 0, n), 0);
      Received& r = got[o.camera_name];
      ++r.objects;
      r.object_seqs.insert(o.frame_seq);
    } else if (ev.channel == "CLUTTERSEG_LABELS") {
      clutterseg::label_image_t l;
      ASSERT_GE(l.decode(ev.data.data(), 0, n), 0);
      ++got[l.camera_name].labels;
    } else if (ev.channel == "CLUTTERSEG_STATUS") {
      clutterseg::status_t s;
      ASSERT_GE(s.decode(ev.data.data(), 0, n), 0);
      ++got[s.camera_name].statuses;
    }
  }
  ASSERT_EQ(got.size(), cameras.size()) << "cameras heard: " << got.size();
  for (const std::string& camera : cameras) {
    SCOPED_TRACE(camera);
    const Received& r = got[camera];
    // Every frame the daemon says it published arrived, once, with its label image.
    EXPECT_EQ(r.objects, published[camera]);
    EXPECT_EQ(static_cast<int64_t>(r.object_seqs.size()), published[camera]);
    EXPECT_EQ(r.labels, published[camera]);
    EXPECT_GE(r.statuses, 1);
  }
}

}  // namespace
}  // namespace clutterseg::daemon
