// Outputs the daemon cannot deliver: an LCM log another daemon writes, a log a killed run left
// torn, a disk that fills up, an LCM transport that refuses every message or never returns;
// and what its sources deliver: damaged or empty frames, the camera.* keys.
// Each run is the real `clutterseg` process on a recording written by clutterseg-synth; the
// checks are on its exit code (5 = finished, not everything delivered), its last log line
// and the files it left.
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/mount.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_cli.h"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using Clock = std::chrono::steady_clock;

class DaemonDelivery : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = testing::ScratchDir("daemon_delivery_" + std::to_string(getpid()));
    recording_ = (dir_ / "scene.oni").string();
    std::string err;
    have_recording_ =
        testutil::Run({CLUTTERSEG_SYNTH_EXE, "--oni", recording_, "--count", "6", "--seed", "5"},
                      std::chrono::minutes(5), &err) == 0;
    if (!have_recording_) std::fprintf(stderr, "clutterseg-synth failed: %s\n", err.c_str());
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  void SetUp() override { ASSERT_TRUE(have_recording_) << "no recording from clutterseg-synth"; }

  static std::string Scratch(const std::string& name) { return (dir_ / name).string(); }

  // The daemon replaying the recording in lockstep to `url`, with `extra` arguments.
  static std::vector<std::string> Args(const std::string& url,
                                       const std::vector<std::string>& extra = {}) {
    return testutil::ReplayArgs(CLUTTERSEG_DAEMON_EXE, recording_, url, extra);
  }

  static inline std::filesystem::path dir_;
  static inline std::string recording_;
  static inline bool have_recording_{false};
};

using testutil::LastLine;

TEST_F(DaemonDelivery, ASecondWriterOfALogIsRefusedAndTheFirstLogStaysWhole) {
  const std::string log = Scratch("shared.lcmlog");
  testutil::Child first =
      testutil::Spawn({CLUTTERSEG_DAEMON_EXE, "--source", recording_, "--speed", "realtime",
                       "--loop", "--lcm-url", "file://" + log + "?mode=w"});
  ASSERT_GT(first.pid, 0);
  // Wait until the first daemon writes.
  for (int i = 0; i < 300 && testutil::ScanLcmLog(log).events < 3; ++i) {
    std::this_thread::sleep_for(milliseconds(20));
  }
  ASSERT_GE(testutil::ScanLcmLog(log).events, 3u) << "the first daemon does not publish";
  for (const char* mode : {"w", "a"}) {
    std::string err;
    const int rc = testutil::Run(Args("file://" + log + "?mode=" + mode), seconds(60), &err);
    EXPECT_EQ(rc, kExitLcmUnavailable) << "mode=" << mode << ":\n" << err;
    EXPECT_NE(err.find("another process is writing it"), std::string::npos) << err;
  }
  ASSERT_EQ(kill(first.pid, SIGTERM), 0);
  std::string err;
  EXPECT_EQ(testutil::Wait(&first, seconds(20), &err), kExitOk) << err;
  const testutil::LcmLogScan scan = testutil::ScanLcmLog(log);
  EXPECT_TRUE(scan.complete) << "the refused writers did not touch it: " << scan.problem;
}

// A FIFO nobody reads would block LCM's writes (and the open); /dev/full accepts nothing;
// /dev/null discards.
TEST_F(DaemonDelivery, ALogThatIsNotARegularFileIsRefused) {
  const std::string fifo = Scratch("log.fifo");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  for (const std::string& path : {fifo, std::string("/dev/full")}) {
    for (const char* mode : {"w", "a"}) {
      std::string err;
      const int rc = testutil::Run(Args("file://" + path + "?mode=" + mode), seconds(60), &err);
      EXPECT_EQ(rc, kExitLcmUnavailable) << path << " mode=" << mode << ":\n" << err;
      EXPECT_NE(err.find(path + " is not a regular file"), std::string::npos) << err;
    }
  }
  // /dev/null is the one device taken: a run whose messages are meant to go nowhere.
  std::string err;
  EXPECT_EQ(testutil::Run(Args("file:///dev/null?mode=w"), seconds(60), &err), kExitOk) << err;
}

TEST_F(DaemonDelivery, ATornLogEndIsCutBeforeAppending) {
  const std::string log = Scratch("append.lcmlog");
  std::string err;
  ASSERT_EQ(testutil::Run(Args("file://" + log + "?mode=w"), seconds(60), &err), kExitOk) << err;
  const testutil::LcmLogScan whole = testutil::ScanLcmLog(log);
  ASSERT_TRUE(whole.complete) << whole.problem;
  // A run killed in the middle of writing its last event.
  std::filesystem::resize_file(log, whole.file_bytes - 7);
  const testutil::LcmLogScan torn = testutil::ScanLcmLog(log);
  ASSERT_FALSE(torn.complete);
  ASSERT_EQ(torn.events, whole.events - 1);

  ASSERT_EQ(testutil::Run(Args("file://" + log + "?mode=a"), seconds(60), &err), kExitOk) << err;
  EXPECT_NE(err.find("cut a torn last event"), std::string::npos) << err;
  const testutil::LcmLogScan appended = testutil::ScanLcmLog(log);
  EXPECT_TRUE(appended.complete) << appended.problem;
  EXPECT_GT(appended.events, torn.events);
  // LCM's reader reaches every event: the first run's (its torn last event was the final
  // status_t), then the second run's.
  const std::vector<testutil::LogEvent> events = testutil::ReadLcmLog(log);
  EXPECT_EQ(events.size(), appended.events);
  size_t objects = 0;
  for (const testutil::LogEvent& ev : events) objects += ev.channel == "CLUTTERSEG_OBJECTS";
  EXPECT_EQ(objects, 2u * 6u) << "six frames from each run";
}

// Damage inside a log (an overwritten sync word with whole events after it) is not a torn end:
// appending used to cut everything after the damage, saying "cut a torn last event". It is
// refused, naming the byte, and the file is left as it was.
TEST_F(DaemonDelivery, ALogDamagedInsideIsRefusedNotCut) {
  const std::string log = Scratch("damaged.lcmlog");
  std::string err;
  ASSERT_EQ(testutil::Run(Args("file://" + log + "?mode=w"), seconds(60), &err), kExitOk) << err;
  std::string bytes;
  {
    std::ifstream in(log, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const size_t second = bytes.find("\xED\xA1\xDA\x01", 4);
  ASSERT_NE(second, std::string::npos);
  bytes[second] = '\x7f';
  {
    std::ofstream out(log, std::ios::binary | std::ios::trunc);
    out << bytes;
  }
  err.clear();
  EXPECT_EQ(testutil::Run(Args("file://" + log + "?mode=a"), seconds(60), &err),
            kExitLcmUnavailable)
      << err;
  EXPECT_NE(err.find("no sync word at byte " + std::to_string(second)), std::string::npos) << err;
  EXPECT_NE(err.find("is damaged inside, not torn at its end"), std::string::npos) << err;
  std::ifstream in(log, std::ios::binary);
  const std::string after((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(after, bytes) << "the refused log was changed";
}

// A small tmpfs that the run fills: the messages that do not fit are counted as failures and
// the log keeps the whole events written; overlays that cannot be written are counted. Both
// end the run with exit code 5 and say what is missing.
TEST_F(DaemonDelivery, AFullDiskEndsWithExitFiveSayingWhatIsMissing) {
  const auto mount_point = dir_ / "small_disk";
  std::filesystem::create_directories(mount_point);
  if (mount("tmpfs", mount_point.c_str(), "tmpfs", 0, "size=256k") != 0) {
    GTEST_SKIP() << "cannot mount a small tmpfs (" << std::strerror(errno)
                 << "); needs root or CAP_SYS_ADMIN";
  }
  struct Unmount {
    std::string path;
    ~Unmount() { umount2(path.c_str(), MNT_DETACH); }
  } unmount{mount_point.string()};

  // The log: depth images (600 kB each) do not fit.
  const std::string log = (mount_point / "out.lcmlog").string();
  std::string err;
  int rc = testutil::Run(Args("file://" + log + "?mode=w", {"--set", "lcm.publish_depth=true"}),
                         seconds(60), &err);
  EXPECT_EQ(rc, kExitIncomplete) << err;
  EXPECT_NE(LastLine(err).find("LCM log " + log + ": "), std::string::npos) << err;
  EXPECT_NE(LastLine(err).find("could not be written (No space left on device)"), std::string::npos)
      << err;
  EXPECT_TRUE(testutil::ScanLcmLog(log).complete);
  std::filesystem::remove(log);

  // Overlays into the full disk, the log elsewhere.
  const auto filler = mount_point / "filler";
  std::vector<char> block(static_cast<size_t>(250) * 1024, 'x');
  {
    std::FILE* f = std::fopen(filler.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(block.data(), 1, block.size(), f);
    std::fclose(f);
  }
  const auto png_dir = mount_point / "overlays";
  std::filesystem::create_directories(png_dir);
  rc = testutil::Run(
      Args("file://" + Scratch("overlays.lcmlog") + "?mode=w", {"--png-dir", png_dir.string()}),
      seconds(60), &err);
  EXPECT_EQ(rc, kExitIncomplete) << err;
  EXPECT_NE(LastLine(err).find("overlay PNGs not written"), std::string::npos) << err;
  // A failed overlay costs that overlay only: every frame was still published.
  size_t objects = 0;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(Scratch("overlays.lcmlog"))) {
    objects += ev.channel == "CLUTTERSEG_OBJECTS";
  }
  EXPECT_EQ(objects, 6u);
}

TEST_F(DaemonDelivery, TcpqWithoutAServerExitsFiveCountingTheRefusals) {
  std::string err;
  const int rc = testutil::Run(Args("tcpq://127.0.0.1:1"), seconds(60), &err);
  EXPECT_EQ(rc, kExitIncomplete) << err;
  EXPECT_NE(LastLine(err).find("messages refused by the LCM transport"), std::string::npos) << err;
}

// A TCP listener on 127.0.0.1 that never accepts, reads or answers: LCM's tcpq client then
// waits for the hub's handshake forever. Returns the socket and its port.
int SilentListener(int* port, int fixed_port = 0) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  const int one = 1;
  setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(static_cast<uint16_t>(fixed_port));
  socklen_t len = sizeof(addr);
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
      getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0 || listen(fd, 4) != 0) {
    close(fd);
    return -1;
  }
  *port = ntohs(addr.sin_port);
  return fd;
}

// The handshake that never completes blocks start-up: the daemon gives up after its start-up
// limit (20 s) with exit code 4, naming the step.
TEST_F(DaemonDelivery, AHubThatNeverAnswersEndsStartUpWithExitFour) {
  int port = 0;
  const int server = SilentListener(&port);
  ASSERT_GE(server, 0);
  const auto t0 = Clock::now();
  std::string err;
  const int rc = testutil::Run(Args("tcpq://127.0.0.1:" + std::to_string(port)), seconds(90), &err);
  const double taken = std::chrono::duration<double>(Clock::now() - t0).count();
  close(server);
  std::printf("silent hub at start-up: exit %d after %.1f s\n", rc, taken);
  ASSERT_NE(rc, -1) << "hung:\n" << err;
  EXPECT_EQ(rc, kExitLcmUnavailable) << err;
  EXPECT_NE(err.find("start-up did not finish in time: opening LCM URL"), std::string::npos) << err;
}

// The hub goes silent while the daemon runs (the first connection was refused; LCM's tcpq
// client reconnects on a later publish and waits for the handshake forever). The publisher
// is stuck, capture and segmentation go on (the LCM sink drops and counts), and SIGTERM still
// ends the daemon by the network transport's stop limit (the message names it; without it the
// drain's 5 s stall limit would end the run with another message): exit 5, saying how many
// frames went unpublished. The time taken is printed, not asserted.
TEST_F(DaemonDelivery, AStalledTransportIsAbandonedWithExitFive) {
  int port = 0;
  const int probe = SilentListener(&port);
  ASSERT_GE(probe, 0);
  close(probe);  // a free port, refused until the listener below takes it
  testutil::Child child =
      testutil::Spawn({CLUTTERSEG_DAEMON_EXE, "--source", recording_, "--speed", "realtime",
                       "--loop", "--lcm-url", "tcpq://127.0.0.1:" + std::to_string(port)});
  ASSERT_GT(child.pid, 0);
  std::this_thread::sleep_for(milliseconds(1500));
  int same_port = 0;
  const int server = SilentListener(&same_port, port);
  ASSERT_GE(server, 0) << "port " << port << " taken meanwhile";
  std::this_thread::sleep_for(milliseconds(1500));
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  const auto t0 = Clock::now();
  std::string err;
  const int rc = testutil::Wait(&child, seconds(60), &err);
  const double taken = std::chrono::duration<double>(Clock::now() - t0).count();
  close(server);
  std::printf("stalled transport: exit %d %.1f s after SIGTERM\n", rc, taken);
  ASSERT_NE(rc, -1) << "hung:\n" << err;
  EXPECT_EQ(rc, kExitIncomplete) << err;
  EXPECT_NE(err.find("did not take the last messages within 900 ms"), std::string::npos) << err;
  EXPECT_NE(err.find("not published"), std::string::npos) << err;
}

// A directory in which one depth image is damaged: the daemon publishes the others, names
// the damaged file as it goes, reports it in status_t and ends with exit code 5.
TEST_F(DaemonDelivery, AFrameTheSourceCannotDeliverEndsWithExitFive) {
  const std::filesystem::path frames = dir_ / "pngs_one_bad";
  std::filesystem::create_directories(frames);
  const core::DepthImage depth(64, 48, uint16_t{900});
  for (int i = 0; i < 4; ++i) {
    io::WriteDepthPng((frames / ("00000" + std::to_string(i) + "-depth.png")).string(), depth);
  }
  std::filesystem::resize_file(frames / "000002-depth.png", 40);  // cut in its IHDR chunk
  const std::string log = Scratch("one_bad.lcmlog");
  std::vector<std::string> argv = Args("file://" + log + "?mode=w");
  argv[2] = frames.string();
  std::string err;
  EXPECT_EQ(testutil::Run(argv, seconds(60), &err), kExitIncomplete) << err;
  EXPECT_NE(err.find("frame not delivered by the source (unreadable)"), std::string::npos) << err;
  EXPECT_NE(err.find("000002-depth.png"), std::string::npos) << err;
  EXPECT_NE(LastLine(err).find("1 frames of the source not delivered (1 unreadable)"),
            std::string::npos)
      << err;
  size_t objects = 0;
  int64_t not_delivered = -1;
  int64_t expected = 0;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
    objects += ev.channel == "CLUTTERSEG_OBJECTS";
    if (ev.channel != "CLUTTERSEG_STATUS") continue;
    clutterseg::status_t st;
    ASSERT_GT(st.decode(ev.data.data(), 0, static_cast<int>(ev.data.size())), 0);
    not_delivered = st.frames_not_delivered;
    expected = st.frames_expected;
  }
  EXPECT_EQ(objects, 3u);
  EXPECT_EQ(not_delivered, 1) << "the last status_t counts the damaged frame";
  EXPECT_EQ(expected, 4);
}

// Depth images without a single measurement (a wrong depth scale, a covered lens): the run
// produces nothing usable and says so with exit code 1.
TEST_F(DaemonDelivery, ASourceOfOnlyEmptyFramesIsAFailure) {
  const std::filesystem::path frames = dir_ / "pngs_empty";
  std::filesystem::create_directories(frames);
  const core::DepthImage depth(64, 48, uint16_t{0});
  for (int i = 0; i < 3; ++i) {
    io::WriteDepthPng((frames / ("00000" + std::to_string(i) + "-depth.png")).string(), depth);
  }
  std::vector<std::string> argv = Args("memq://");
  argv[2] = frames.string();
  std::string err;
  EXPECT_EQ(testutil::Run(argv, seconds(60), &err), kExitFailure) << err;
  EXPECT_NE(err.find("every one of the 3 frames the source delivered was empty"), std::string::npos)
      << err;
}

// camera.depth_scale_mm reaches a depth-PNG directory: a scale that puts every pixel at 0 mm
// leaves nothing to segment (exit 1), the default scale segments the same frames.
TEST_F(DaemonDelivery, TheDepthScaleKeyReachesADepthPngDirectory) {
  const std::filesystem::path frames = dir_ / "pngs_scaled";
  std::filesystem::create_directories(frames);
  const core::DepthImage depth(64, 48, uint16_t{4500});  // TUM units: 0.9 m
  for (int i = 0; i < 2; ++i) {
    io::WriteDepthPng((frames / ("00000" + std::to_string(i) + "-depth.png")).string(), depth);
  }
  std::vector<std::string> argv = Args("memq://", {"--set", "camera.depth_scale_mm=0.0001"});
  argv[2] = frames.string();
  std::string err;
  EXPECT_EQ(testutil::Run(argv, seconds(60), &err), kExitFailure) << err;
  EXPECT_NE(err.find("was empty"), std::string::npos) << err;
  argv = Args("memq://", {"--set", "camera.depth_scale_mm=0.2"});
  argv[2] = frames.string();
  EXPECT_EQ(testutil::Run(argv, seconds(60), &err), kExitOk) << err;
}

// camera.intrinsics_file replaces a recording's field of view: a calibration of the same
// aspect ratio is used (and said so), another aspect ratio or an unreadable file is refused.
TEST_F(DaemonDelivery, CalibratedIntrinsicsReplaceTheRecordingsFieldOfView) {
  const auto write = [](const std::string& path, const std::string& json) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs(json.c_str(), f);
    std::fclose(f);
  };
  const std::string good = Scratch("calibrated.json");
  write(good, R"({"fx": 1050.0, "fy": 1050.0, "cx": 639.5, "cy": 479.5, "width": 1280,
                  "height": 960})");
  std::string err;
  EXPECT_EQ(testutil::Run(Args("memq://",
                               {"--set", "camera.intrinsics_file=" + good, "--log-level", "debug"}),
                          seconds(60), &err),
            kExitOk)
      << err;
  EXPECT_NE(err.find("calibrated intrinsics"), std::string::npos) << err;

  // The same calibration as a ROS camera_info file.
  const std::string info = Scratch("calibrated.yaml");
  write(info,
        "image_width: 1280\nimage_height: 960\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
        "  data: [1050, 0, 639.5, 0, 1050, 479.5, 0, 0, 1]\n");
  err.clear();
  EXPECT_EQ(testutil::Run(Args("memq://", {"--set", "camera.intrinsics_file=" + info}), seconds(60),
                          &err),
            kExitOk)
      << err;
  EXPECT_NE(err.find("calibrated intrinsics"), std::string::npos) << err;

  const std::string wide = Scratch("wide.json");
  write(wide, R"({"fx": 600.0, "fy": 600.0, "cx": 639.5, "cy": 359.5, "width": 1280,
                  "height": 720})");
  err.clear();
  EXPECT_EQ(testutil::Run(Args("memq://", {"--set", "camera.intrinsics_file=" + wide}), seconds(60),
                          &err),
            kExitSourceUnavailable)
      << err;
  EXPECT_NE(err.find("another aspect ratio"), std::string::npos) << err;

  err.clear();
  EXPECT_EQ(
      testutil::Run(Args("memq://", {"--set", "camera.intrinsics_file=" + Scratch("missing.json")}),
                    seconds(60), &err),
      kExitUsage)
      << err;
  EXPECT_NE(err.find("camera.intrinsics_file"), std::string::npos) << err;
}

// A frame beyond segmenter.objects.max_objects is still published (the largest objects) and
// counted: status_t.frames_capped and a warning naming the key.
TEST_F(DaemonDelivery, FramesReachingTheObjectCapAreCountedAndNamed) {
  const std::string log = Scratch("capped.lcmlog");
  std::string err;
  ASSERT_EQ(
      testutil::Run(Args("file://" + log + "?mode=w", {"--set", "segmenter.objects.max_objects=1"}),
                    seconds(60), &err),
      kExitOk)
      << err;
  EXPECT_NE(err.find("more objects than segmenter.objects.max_objects = 1"), std::string::npos)
      << err;
  int64_t capped = -1;
  size_t objects = 0;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
    if (ev.channel == "CLUTTERSEG_OBJECTS") {
      clutterseg::objects_t o;
      ASSERT_GT(o.decode(ev.data.data(), 0, static_cast<int>(ev.data.size())), 0);
      EXPECT_LE(o.num_objects, 1);
      ++objects;
    } else if (ev.channel == "CLUTTERSEG_STATUS") {
      clutterseg::status_t st;
      ASSERT_GT(st.decode(ev.data.data(), 0, static_cast<int>(ev.data.size())), 0);
      capped = st.frames_capped;
    }
  }
  EXPECT_EQ(objects, 6u);
  EXPECT_GT(capped, 0) << "the synthetic scenes hold several objects each";
  EXPECT_LE(capped, 6);
}

TEST_F(DaemonDelivery, NegativeCountsOnTheCommandLineAreUsageErrors) {
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{"--max-frames", "-1"}, {"--threads", "-2"}}) {
    std::string err;
    const int rc = testutil::Run(Args("memq://", extra), seconds(60), &err);
    EXPECT_EQ(rc, kExitUsage) << extra[0] << " " << extra[1] << ":\n" << err;
    EXPECT_NE(err.find(extra[0]), std::string::npos) << err;
  }
}

}  // namespace
}  // namespace clutterseg::daemon
