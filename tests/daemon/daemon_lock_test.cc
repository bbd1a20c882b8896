// The per-camera instance lock of the daemon, on real `clutterseg` processes: two daemons of
// one camera name started together on one udpm bus (inside a private network namespace), two
// camera names side by side, a lock left by a killed daemon, a lock directory that cannot be
// written.
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

using std::chrono::seconds;

constexpr char kUrl[] = "udpm://239.255.76.67:7667?ttl=0";

class DaemonLock : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = testing::ScratchDir("daemon_lock");
    oni_path_ = (dir_ / "tabletop.oni").string();
    testutil::WriteTabletopOni(oni_path_, 30);
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  // A daemon replaying the recording in real time into `url`, locking in `lock_dir`.
  static std::vector<std::string> Daemon(const std::string& camera, const std::string& lock_dir,
                                         const std::string& url, int max_frames) {
    std::vector<std::string> argv =
        testutil::LoopingDaemonArgv(CLUTTERSEG_DAEMON_EXE, oni_path_, url, camera, lock_dir);
    argv.insert(argv.end(), {"--max-frames", std::to_string(max_frames)});
    return argv;
  }

  static inline std::filesystem::path dir_;
  static inline std::string oni_path_;
};

TEST_F(DaemonLock, SameCameraStartedTogetherRunsOnceAndPublishesOnce) {
  testutil::NetNamespace ns(/*route=*/true);
  if (!ns.ok()) GTEST_SKIP() << "skipped: " << ns.why();
  const std::string lock_dir = (dir_ / "race_locks").string();
  constexpr int kFrames = 8;
  for (int round = 0; round < 5; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const std::string log = (dir_ / ("race" + std::to_string(round) + ".lcmlog")).string();
    testutil::Child logger =
        testutil::Spawn(ns.Exec({"lcm-logger", std::string("--lcm-url=") + kUrl, "-f", log}));
    ASSERT_GT(logger.pid, 0);
    ASSERT_TRUE(testutil::WaitForMulticastMember(ns, "239.255.76.67", seconds(20)))
        << "the logger never joined the group";

    // Back to back, no delay between them.
    testutil::Child a = testutil::Spawn(ns.Exec(Daemon("arm", lock_dir, kUrl, kFrames)));
    testutil::Child b = testutil::Spawn(ns.Exec(Daemon("arm", lock_dir, kUrl, kFrames)));
    ASSERT_GT(a.pid, 0);
    ASSERT_GT(b.pid, 0);
    std::string a_err, b_err;
    const int a_rc = testutil::Wait(&a, seconds(60), &a_err);
    const int b_rc = testutil::Wait(&b, seconds(60), &b_err);
    ASSERT_EQ(kill(logger.pid, SIGINT), 0);
    std::string logger_err;
    testutil::Wait(&logger, seconds(20), &logger_err);

    ASSERT_EQ(std::multiset<int>({a_rc, b_rc}), std::multiset<int>({kExitOk, kExitUsage}))
        << "first:\n"
        << a_err << "\nsecond:\n"
        << b_err;
    const std::string& refused = a_rc == kExitUsage ? a_err : b_err;

    std::set<int32_t> status_pids;
    std::set<int64_t> frame_seqs;
    int objects = 0;
    for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
      const int n = static_cast<int>(ev.data.size());
      if (ev.channel == "CLUTTERSEG_STATUS") {
        clutterseg::status_t s;
        ASSERT_GE(s.decode(ev.data.data(), 0, n), 0);
        EXPECT_EQ(s.camera_name, "arm");
        status_pids.insert(s.pid);
      } else if (ev.channel == "CLUTTERSEG_OBJECTS") {
        clutterseg::objects_t o;
        ASSERT_GE(o.decode(ev.data.data(), 0, n), 0);
        ++objects;
        frame_seqs.insert(o.frame_seq);
      }
    }
    // One publisher: its status reports name one pid, and no frame was published twice.
    ASSERT_EQ(status_pids.size(), 1u) << logger_err;
    EXPECT_EQ(objects, kFrames);
    EXPECT_EQ(static_cast<int>(frame_seqs.size()), objects);
    const std::string winner = std::to_string(*status_pids.begin());
    EXPECT_NE(refused.find("already runs camera 'arm' on this host"), std::string::npos) << refused;
    EXPECT_NE(refused.find("(pid " + winner), std::string::npos) << refused;
    EXPECT_NE(refused.find(lock_dir + "/arm.lock"), std::string::npos) << refused;
  }
}

TEST_F(DaemonLock, TwoCameraNamesRunSideBySide) {
  testutil::NetNamespace ns(/*route=*/true);
  if (!ns.ok()) GTEST_SKIP() << "skipped: " << ns.why();
  const std::string lock_dir = (dir_ / "pair_locks").string();
  testutil::Child a = testutil::Spawn(ns.Exec(Daemon("left", lock_dir, kUrl, 8)));
  testutil::Child b = testutil::Spawn(ns.Exec(Daemon("right", lock_dir, kUrl, 8)));
  std::string a_err, b_err;
  EXPECT_EQ(testutil::Wait(&a, seconds(60), &a_err), kExitOk) << a_err;
  EXPECT_EQ(testutil::Wait(&b, seconds(60), &b_err), kExitOk) << b_err;
  EXPECT_TRUE(std::filesystem::exists(lock_dir + "/left.lock"));
  EXPECT_TRUE(std::filesystem::exists(lock_dir + "/right.lock"));
}

TEST_F(DaemonLock, KilledDaemonLeavesTheLockFree) {
  testutil::NetNamespace ns(/*route=*/true);
  if (!ns.ok()) GTEST_SKIP() << "skipped: " << ns.why();
  const std::string lock_dir = (dir_ / "kill_locks").string();
  testutil::Child first = testutil::Spawn(ns.Exec(Daemon("arm", lock_dir, kUrl, 0)));
  ASSERT_GT(first.pid, 0);
  // Wait until it holds the lock (its pid is in the file), then a second one is refused.
  const std::string lock_file = lock_dir + "/arm.lock";
  for (int i = 0; i < 600 && !(std::filesystem::exists(lock_file) &&
                               std::filesystem::file_size(lock_file) > 0);
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  std::string err;
  EXPECT_EQ(testutil::Run(ns.Exec(Daemon("arm", lock_dir, kUrl, 5)), seconds(60), &err), kExitUsage)
      << err;
  EXPECT_NE(err.find("already runs camera 'arm'"), std::string::npos) << err;
  ASSERT_EQ(kill(first.pid, SIGKILL), 0);
  std::string first_err;
  testutil::Wait(&first, seconds(20), &first_err);
  ASSERT_TRUE(std::filesystem::exists(lock_file)) << "the file stays, unlocked";

  err.clear();
  EXPECT_EQ(testutil::Run(ns.Exec(Daemon("arm", lock_dir, kUrl, 5)), seconds(60), &err), kExitOk)
      << err;
}

TEST_F(DaemonLock, UnwritableLockDirectoryIsAClearError) {
  // A path below a regular file cannot be created by anyone, root included.
  const std::filesystem::path file = dir_ / "not_a_dir";
  std::ofstream(file.string()) << "x";
  const std::string lock_dir = (file / "locks").string();
  std::string err;
  EXPECT_EQ(testutil::Run(Daemon("arm", lock_dir, "tcpq://127.0.0.1:1", 5), seconds(60), &err),
            kExitUsage)
      << err;
  EXPECT_NE(err.find("lcm.lock_dir = '" + lock_dir + "'"), std::string::npos) << err;
  EXPECT_NE(err.find("cannot create the lock directory"), std::string::npos) << err;
}

TEST_F(DaemonLock, ReplayIntoAFileOrMemqTakesNoLock) {
  const std::string lock_dir = (dir_ / "replay_locks").string();
  std::string err;
  const std::string log = (dir_ / "replay.lcmlog").string();
  EXPECT_EQ(
      testutil::Run(Daemon("camera", lock_dir, "file://" + log + "?mode=w", 5), seconds(60), &err),
      kExitOk)
      << err;
  EXPECT_EQ(testutil::Run(Daemon("camera", lock_dir, "memq://", 5), seconds(60), &err), kExitOk)
      << err;
  EXPECT_FALSE(std::filesystem::exists(lock_dir)) << "memq:// and file:// publish nowhere shared";
}

}  // namespace
}  // namespace clutterseg::daemon
