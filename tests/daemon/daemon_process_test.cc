// End-to-end tests of the `clutterseg` executable: exit codes, signals and LCM logs.
#include <sched.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>

#include "clutterseg/daemon/daemon.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "clutterseg/version.h"
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

// Scheduling of one thread of a process: its name, class (SCHED_OTHER 0, SCHED_FIFO 1) and
// real-time priority, from /proc/PID/task/TID.
struct ThreadSched {
  pid_t tid{0};
  std::string name;
  int policy{-1};
  int rt_priority{-1};
};

std::vector<ThreadSched> ProcessThreads(pid_t pid) {
  std::vector<ThreadSched> threads;
  std::error_code ec;
  const std::filesystem::path task = "/proc/" + std::to_string(pid) + "/task";
  for (const auto& entry : std::filesystem::directory_iterator(task, ec)) {
    ThreadSched t;
    t.tid = static_cast<pid_t>(std::stol(entry.path().filename().string()));
    std::ifstream comm(entry.path() / "comm");
    std::getline(comm, t.name);
    std::ifstream stat_file(entry.path() / "stat");
    std::string stat((std::istreambuf_iterator<char>(stat_file)), {});
    // Fields after the ")" closing the name start at field 3; rt_priority is 40, policy 41.
    const size_t close = stat.rfind(')');
    if (t.name.empty() || close == std::string::npos) continue;
    std::istringstream fields(stat.substr(close + 2));
    std::string field;
    for (int i = 3; i <= 41 && fields >> field; ++i) {
      if (i == 40) t.rt_priority = std::stoi(field);
      if (i == 41) t.policy = std::stoi(field);
    }
    threads.push_back(t);
  }
  return threads;
}

class DaemonProcess : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    oni_path_ =
        (testing::ScratchDir("daemon_process_oni_" + std::to_string(getpid())) / "tabletop5.oni")
            .string();
    testutil::WriteTabletopOni(oni_path_, kFrames);
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    std::filesystem::remove_all(std::filesystem::path(oni_path_).parent_path(), ec);
  }
  static constexpr int kFrames = 5;
  static inline std::string oni_path_;
};

TEST_F(DaemonProcess, OniRecordingToFileLogOneObjectsPerFrame) {
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

// Two daemons on two cameras publish on one udpm bus and are told apart by camera name; a
// Python subscriber with our own transport (Debian has no python3-lcm) receives both and
// decodes their label images.
TEST_F(DaemonProcess, TwoCamerasOnOneUdpmBusReachAPythonSubscriber) {
  testutil::NetNamespace ns(/*route=*/true);
  if (!ns.ok()) GTEST_SKIP() << "skipped: " << ns.why();
  const std::string url = "udpm://239.255.76.67:7667?ttl=0";
  const auto dir = testing::ScratchDir("daemon_process_two_cameras");
  const auto ready = dir / "ready";
  const std::string script =
      std::string(CLUTTERSEG_SOURCE_DIR) + "/tests/daemon/python_udpm_subscriber.py";
  std::string err;
  testutil::Child sub = testutil::Spawn(ns.Exec(
      {"/usr/bin/env", std::string("PYTHONPATH=") + CLUTTERSEG_PYTHON_BINDINGS, "python3", script,
       url + "&recv_buf_size=4194304", ready.string(), std::to_string(kFrames), "left", "right"}));
  ASSERT_GT(sub.pid, 0);
  for (int i = 0; i < 1000 && !std::filesystem::exists(ready); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(std::filesystem::exists(ready)) << "the Python subscriber did not start";
  testutil::Child left =
      testutil::Spawn(ns.Exec({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "max",
                               "--lcm-url", url, "--set", "camera_name=left"}));
  testutil::Child right =
      testutil::Spawn(ns.Exec({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "max",
                               "--lcm-url", url, "--set", "camera_name=right"}));
  EXPECT_EQ(testutil::Wait(&left, std::chrono::minutes(5), &err), 0) << err;
  EXPECT_EQ(testutil::Wait(&right, std::chrono::minutes(5), &err), 0) << err;
  std::string sub_err;
  EXPECT_EQ(testutil::Wait(&sub, seconds(90), &sub_err), 0) << sub_err;
}

// Two daemons of one camera on one bus would interleave their objects_t: the second is
// refused (exit 2) after listening one status period, naming the first; told to skip the
// check it runs, and the first reports the clash.
TEST_F(DaemonProcess, SameCameraTwiceOnOneUdpmBusIsRefused) {
  testutil::NetNamespace ns(/*route=*/true);
  if (!ns.ok()) GTEST_SKIP() << "skipped: " << ns.why();
  const std::string url = "udpm://239.255.76.67:7667?ttl=0";
  const std::string locks = testing::ScratchDir("daemon_process_locks").string();
  auto daemon = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> argv =
        testutil::LoopingDaemonArgv(CLUTTERSEG_DAEMON_EXE, oni_path_, url, "arm", locks);
    argv.insert(argv.end(), extra.begin(), extra.end());
    return ns.Exec(argv);
  };
  testutil::Child first = testutil::Spawn(daemon({}));
  ASSERT_GT(first.pid, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));  // its check, then a status

  std::string err;
  const auto t0 = std::chrono::steady_clock::now();
  // A lock directory of its own stands for a daemon on another host of the bus: the host's
  // lock (daemon_lock_test.cc) does not see it, the bus watch does.
  const auto other_host = testing::ScratchDir("daemon_process_other_host");
  EXPECT_EQ(
      testutil::Run(daemon({"--max-frames", "5", "--set", "lcm.lock_dir=" + other_host.string()}),
                    seconds(60), &err),
      kExitUsage)
      << err;
  std::printf("second daemon refused after %.1f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  EXPECT_NE(err.find("already publishes camera 'arm' on CLUTTERSEG_STATUS"), std::string::npos)
      << err;
  EXPECT_NE(err.find("pid "), std::string::npos) << err;

  EXPECT_EQ(testutil::Run(daemon({"--max-frames", "60", "--set", "lcm.check_instances=false"}),
                          seconds(60), &err),
            kExitOk)
      << err;
  ASSERT_EQ(kill(first.pid, SIGTERM), 0);
  std::string first_err;
  EXPECT_EQ(testutil::Wait(&first, seconds(20), &first_err), kExitOk) << first_err;
  EXPECT_NE(first_err.find("already publishes camera 'arm'"), std::string::npos)
      << "the running daemon reports the clash:\n"
      << first_err;
}

// Sets an environment variable for the scope (the spawned daemon inherits it).
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    const char* old = std::getenv(name);
    if (old != nullptr) old_ = old;
    had_ = old != nullptr;
    setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (had_) {
      setenv(name_, old_.c_str(), 1);
    } else {
      unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::string old_;
  bool had_{false};
};

TEST_F(DaemonProcess, TellsSystemdWhenReadyAndKeepsTheWatchdogAlive) {
  // A notification socket as systemd offers one to a Type=notify unit.
  const auto dir = testing::ScratchDir("daemon_process_notify");
  const std::string path = (dir / "notify.sock").string();
  const int sock = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(sock, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", path.c_str());
  ASSERT_EQ(bind(sock, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  const timeval tv{0, 100000};
  setsockopt(sock, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
  // Read as systemd does, while the daemon runs: a notification socket nobody reads fills up
  // and blocks the sender.
  std::vector<std::string> messages;
  std::atomic<bool> done{false};
  std::thread reader([&] {
    char buf[4096];
    while (!done.load()) {
      const ssize_t n = recv(sock, buf, sizeof(buf), 0);
      if (n > 0) messages.emplace_back(buf, static_cast<size_t>(n));
    }
  });
  std::string err;
  int rc = -1;
  {
    ScopedEnv notify("NOTIFY_SOCKET", path);
    ScopedEnv watchdog("WATCHDOG_USEC", "5000000");
    // The 5-frame recording looped at its 30 Hz for about two seconds.
    testutil::Child child =
        testutil::Spawn({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "realtime",
                         "--loop", "--max-frames", "60", "--lcm-url", "memq://"});
    rc = testutil::Wait(&child, std::chrono::minutes(2), &err);
  }
  done = true;
  reader.join();
  close(sock);
  ASSERT_EQ(rc, 0) << err;
  int ready = 0, keepalive = 0, status = 0;
  for (const std::string& m : messages) {
    ready += m.find("READY=1") != std::string::npos ? 1 : 0;
    keepalive += m == "WATCHDOG=1" ? 1 : 0;
    status += m.rfind("STATUS=", 0) == 0 && m.find("frames published") != std::string::npos;
  }
  EXPECT_EQ(ready, 1) << "READY=1 exactly once, after the source and LCM opened";
  EXPECT_GE(keepalive, 2) << "a keep-alive at least every half watchdog period while publishing";
  EXPECT_GE(status, 1);
}

TEST_F(DaemonProcess, LogLinesCarryJournalPrioritiesUnderJournald) {
  const auto dir = testing::ScratchDir("daemon_process_journal");
  const std::string err_file = (dir / "stderr.txt").string();
  std::ofstream(err_file).close();
  struct stat st {};
  ASSERT_EQ(stat(err_file.c_str(), &st), 0);
  std::string err;
  int rc = -1;
  {
    // systemd names the journal stream it gives a service as JOURNAL_STREAM=dev:ino.
    ScopedEnv journal("JOURNAL_STREAM",
                      std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino));
    rc = testutil::Run(
        {"/bin/sh", "-c",
         std::string("exec '") + CLUTTERSEG_DAEMON_EXE +
             "' --speed max --lcm-url memq:// --source /nonexistent.oni 2>> '" + err_file + "'"},
        std::chrono::minutes(2), &err);
  }
  EXPECT_EQ(rc, kExitSourceUnavailable);
  std::ifstream in(err_file);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // The failure is an error-priority line; nothing is printed without a priority.
  EXPECT_NE(text.find("<3>"), std::string::npos) << text;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) continue;
    EXPECT_EQ(line[0], '<') << "a line without priority: " << line;
  }
}

TEST_F(DaemonProcess, HonoursLcmDefaultUrlAndPrintsItsVersion) {
  const auto log = testing::ScratchDir("daemon_process_default_url") / "env.lcmlog";
  std::string err;
  int rc = -1;
  {
    ScopedEnv url("LCM_DEFAULT_URL", "file://" + log.string() + "?mode=w");
    rc = testutil::Run({CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "max"},
                       std::chrono::minutes(2), &err);
  }
  ASSERT_EQ(rc, 0) << err;
  int objects = 0;
  for (const auto& ev : testutil::ReadLcmLog(log.string())) {
    objects += ev.channel == "CLUTTERSEG_OBJECTS" ? 1 : 0;
  }
  EXPECT_EQ(objects, kFrames) << "published to LCM_DEFAULT_URL when lcm.url is empty";
  // --version: the project's version, exit 0.
  const std::string out_file = (log.parent_path() / "version.txt").string();
  ASSERT_EQ(testutil::Run({"/bin/sh", "-c",
                           std::string("exec '") + CLUTTERSEG_DAEMON_EXE + "' --version > '" +
                               out_file + "'"},
                          std::chrono::seconds(30), &err),
            0)
      << err;
  std::ifstream in(out_file);
  std::string version;
  std::getline(in, version);
  EXPECT_EQ(version, std::string("clutterseg ") + kVersion);
}

TEST_F(DaemonProcess, RealtimePriorityPutsTheLanesBelowTheCapturePath) {
  const auto dir = testing::ScratchDir("daemon_process_realtime");
  const auto log = dir / "out.lcmlog";
  testutil::Child child = testutil::Spawn(
      {CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", "realtime", "--loop", "--threads",
       "1", "--set", "processing.realtime_priority=5", "--png-dir", (dir / "png").string(),
       "--lcm-url", "file://" + log.string() + "?mode=w"});
  ASSERT_GT(child.pid, 0);
  // Started once frames reach the log: every thread is running by then.
  std::vector<ThreadSched> threads;
  for (int i = 0; i < 1000; ++i) {
    std::error_code ec;
    if (std::filesystem::file_size(log, ec) > 100000 && !ec) {
      threads = ProcessThreads(child.pid);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  std::string err;
  ASSERT_EQ(testutil::Wait(&child, seconds(30), &err), 0) << err;
  ASSERT_FALSE(threads.empty()) << "no frame reached the log: " << err;
  std::map<std::string, std::vector<ThreadSched>> by_name;
  for (const auto& t : threads) by_name[t.name].push_back(t);
  for (const char* name :
       {"cs-lane0", "cs-capture", "cs-publish", "cs-dispatch", "cs-overlay", "cs-signals"}) {
    ASSERT_EQ(by_name[name].size(), 1u) << name;
  }
  const auto sched = [&](const char* name) { return by_name[name][0]; };
  if (err.find("running in the normal scheduling class") != std::string::npos) {
    // A kernel or container that refuses SCHED_FIFO even to this process: it says so (checked
    // where it is certain to be refused, below) and every thread runs in the normal class.
    for (const auto& t : threads) EXPECT_EQ(t.policy, 0) << t.name;
    return;
  }
  EXPECT_NE(err.find("segmentation at priority 5, capture and publishing at 6"), std::string::npos)
      << err;
  for (const char* lane : {"cs-lane0", "cs-lane1"}) {
    EXPECT_EQ(sched(lane).policy, SCHED_FIFO) << lane;
    EXPECT_EQ(sched(lane).rt_priority, 5) << lane;
  }
  for (const char* io : {"cs-capture", "cs-publish", "cs-dispatch", "cs-status"}) {
    EXPECT_EQ(sched(io).policy, SCHED_FIFO) << io;
    EXPECT_EQ(sched(io).rt_priority, 6) << io;
  }
  // The overlay PNGs at nice 19, the signal thread, the main thread and the source driver's
  // own threads (OpenNI2's, unnamed; its player busy-waits at the end of a recording) in the
  // normal class.
  EXPECT_EQ(sched("cs-overlay").policy, SCHED_OTHER);
  EXPECT_EQ(sched("cs-signals").policy, SCHED_OTHER);
  ASSERT_GE(by_name["clutterseg"].size(), 2u) << "the main thread and the driver's";
  for (const auto& t : by_name["clutterseg"]) EXPECT_EQ(t.policy, SCHED_OTHER) << t.tid;
}

TEST_F(DaemonProcess, RealtimeReplaysEndOnTheirOwnAtTheEndOfTheRecording) {
  // OniFile's player thread busy-waits once the recording has ended, until its streams stop:
  // in a real-time class it kept the capture thread, of its priority, off both cores, and the
  // daemon never saw the end (it ran until killed, 95 % of both cores in the real-time class).
  for (const char* speed : {"max", "realtime"}) {
    const auto log = testing::ScratchDir("daemon_process_realtime_end") / "out.lcmlog";
    std::string err;
    const int rc = testutil::Run(
        {CLUTTERSEG_DAEMON_EXE, "--source", oni_path_, "--speed", speed, "--set",
         "processing.realtime_priority=5", "--lcm-url", "file://" + log.string() + "?mode=w"},
        std::chrono::seconds(60), &err);
    EXPECT_EQ(rc, 0) << speed << ": " << err;
    int objects = 0;
    for (const auto& ev : testutil::ReadLcmLog(log.string())) {
      objects += ev.channel == "CLUTTERSEG_OBJECTS" ? 1 : 0;
    }
    EXPECT_EQ(objects, kFrames) << speed;
  }
}

TEST_F(DaemonProcess, RealtimeRefusedRunsInTheNormalClassAndSaysWhy) {
  // An unprivileged user with RLIMIT_RTPRIO 0 (no systemd LimitRTPRIO=): the kernel refuses.
  if (geteuid() != 0 || access("/usr/bin/setpriv", X_OK) != 0 ||
      access("/usr/bin/prlimit", X_OK) != 0) {
    GTEST_SKIP() << "needs root, setpriv and prlimit (util-linux) to run the daemon unprivileged";
  }
  char tmpl[] = "/tmp/clutterseg_rt_XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  const std::filesystem::path dir = tmpl;
  std::filesystem::copy_file(oni_path_, dir / "in.oni");
  ASSERT_EQ(chmod(dir.c_str(), 0777), 0);
  ASSERT_EQ(chmod((dir / "in.oni").c_str(), 0644), 0);
  const auto log = dir / "out.lcmlog";
  std::string err;
  const int rc = testutil::Run(
      {"/usr/bin/prlimit", "--rtprio=0:0", "--", "/usr/bin/setpriv", "--reuid=65534",
       "--regid=65534", "--clear-groups", "--inh-caps=-all", CLUTTERSEG_DAEMON_EXE, "--source",
       (dir / "in.oni").string(), "--speed", "max", "--set", "processing.realtime_priority=5",
       "--lcm-url", "file://" + log.string() + "?mode=w"},
      std::chrono::minutes(2), &err);
  EXPECT_EQ(rc, 0) << err;
  EXPECT_NE(err.find("processing.realtime_priority = 5: cannot enter SCHED_FIFO at priority 5: "
                     "Operation not permitted (needs CAP_SYS_NICE or RLIMIT_RTPRIO >= 5"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("running in the normal scheduling class"), std::string::npos) << err;
  int objects = 0;
  for (const auto& ev : testutil::ReadLcmLog(log.string())) {
    objects += ev.channel == "CLUTTERSEG_OBJECTS" ? 1 : 0;
  }
  EXPECT_EQ(objects, kFrames);
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

}  // namespace
}  // namespace clutterseg::daemon
