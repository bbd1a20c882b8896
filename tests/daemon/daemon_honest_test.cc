// What the daemon says it delivered must be what it delivered, to the last byte: the counts of
// a run whose file:// log fills the disk, overlay PNGs on a full disk, a configuration file with
// a second YAML document, a source whose depth is in another unit, --print-config to a full
// device. Each run is the real `clutterseg` process on inputs the test writes itself
// (clutterseg-synth recordings, depth PNGs from the project's PNG writer); full file systems
// are real: a small tmpfs in a private mount namespace (root only; skipped otherwise) and
// /dev/full.
#include <sched.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/wait.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/core/frame.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_cli.h"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

using testutil::DoneCount;
using testutil::LastLine;

// Writes `text` to `path`.
void WriteTextFile(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

class DaemonHonest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // A private mount namespace (before any thread exists: unshare refuses a threaded
    // process), its mounts private, so that the tmpfs of a test is seen by this process and its
    // children only and goes away with them.
    if (unshare(CLONE_NEWNS) != 0) {
      no_mounts_ = std::string("unshare(CLONE_NEWNS): ") + std::strerror(errno);
    } else if (mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) {
      no_mounts_ = std::string("making / private: ") + std::strerror(errno);
    }
    dir_ = testing::ScratchDir("daemon_honest");
    recording_ = (dir_ / "scene.oni").string();
    std::string err;
    have_recording_ = testutil::Run({CLUTTERSEG_SYNTH_EXE, "--oni", recording_, "--count", "100",
                                     "--seed", "5", "--width", "160", "--height", "120"},
                                    std::chrono::minutes(5), &err) == 0;
    if (!have_recording_) std::fprintf(stderr, "clutterseg-synth failed: %s\n", err.c_str());
  }
  static void TearDownTestSuite() {
    for (const std::string& m : mounts_) umount2(m.c_str(), MNT_DETACH);
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // Mounts a tmpfs of `size` (e.g. "64k") on a fresh directory; "" when that is not possible
  // (then the test skips with the reason in *why).
  static std::string SmallDisk(const std::string& name, const std::string& size, std::string* why) {
    if (!no_mounts_.empty()) {
      *why = no_mounts_ + "; a full file system needs root or CAP_SYS_ADMIN";
      return {};
    }
    const fs::path mount_point = dir_ / name;
    fs::create_directories(mount_point);
    if (mount("tmpfs", mount_point.c_str(), "tmpfs", 0, ("size=" + size).c_str()) != 0) {
      *why = std::string("cannot mount a tmpfs: ") + std::strerror(errno);
      return {};
    }
    mounts_.push_back(mount_point.string());
    return mount_point.string();
  }

  // The daemon replaying the recording in lockstep to `url`, with `extra` arguments.
  static std::vector<std::string> Args(const std::string& url,
                                       const std::vector<std::string>& extra = {}) {
    return testutil::ReplayArgs(CLUTTERSEG_DAEMON_EXE, recording_, url, extra);
  }

  static inline fs::path dir_;
  static inline std::string recording_;
  static inline bool have_recording_{false};
  static inline std::string no_mounts_;
  static inline std::vector<std::string> mounts_;
};

// The run fills a 64 KiB tmpfs with its file:// log after a few dozen of its 100 frames. Every
// count the daemon gives (status line, status_t, final line) is what reached the log: the
// log is whole, holds exactly the objects_t messages the final line calls published, and
// every status_t in it counts no more published frames than precede it.
TEST_F(DaemonHonest, AFullDiskUnderTheLogIsCountedAsWhatReachedTheLog) {
  ASSERT_TRUE(have_recording_);
  std::string why;
  const std::string disk = SmallDisk("log_disk", "64k", &why);
  if (disk.empty()) GTEST_SKIP() << why;
  const std::string log = disk + "/out.lcmlog";
  std::string err;
  const int rc = testutil::Run(Args("file://" + log + "?mode=w"), seconds(120), &err);
  EXPECT_EQ(rc, kExitIncomplete) << err;
  EXPECT_NE(LastLine(err).find("No space left on device"), std::string::npos) << err;

  const testutil::LcmLogScan scan = testutil::ScanLcmLog(log);
  EXPECT_TRUE(scan.complete) << "whole events only: " << scan.problem;
  const std::vector<testutil::LogEvent> events = testutil::ReadLcmLog(log);
  EXPECT_EQ(events.size(), scan.events);
  int64_t objects = 0;
  int statuses = 0;
  for (const testutil::LogEvent& ev : events) {
    if (ev.channel == "CLUTTERSEG_OBJECTS") ++objects;
    if (ev.channel != "CLUTTERSEG_STATUS") continue;
    clutterseg::status_t s;
    ASSERT_EQ(s.decode(ev.data.data(), 0, static_cast<int>(ev.data.size())),
              static_cast<int>(ev.data.size()));
    EXPECT_LE(s.frames_published, objects) << "a status_t claims frames the log does not hold";
    ++statuses;
  }
  EXPECT_GT(objects, 0);
  EXPECT_LT(objects, 100) << "the disk was meant to fill up";
  EXPECT_EQ(DoneCount(err, "published"), objects) << err;
  // Every message offered is either in the log or counted as a failure.
  const int64_t failures = DoneCount(err, "publish failures");
  EXPECT_GT(failures, 0) << err;
  EXPECT_NE(LastLine(err).find(std::to_string(failures) + " of the " +
                               std::to_string(failures + static_cast<int64_t>(events.size())) +
                               " messages could not be written"),
            std::string::npos)
      << err;
  // The last status line (stderr) agrees with the final line.
  const size_t status_line = err.rfind("| published ");
  ASSERT_NE(status_line, std::string::npos) << err;
  EXPECT_EQ(std::stoll(err.substr(status_line + 12)), objects) << err;
  std::printf("log: %lld objects_t, %zu events, %d status_t; %lld publish failures\n",
              static_cast<long long>(objects), events.size(), statuses,
              static_cast<long long>(failures));
}

// Overlay PNGs on a 128 KiB tmpfs: the first few fit, the rest do not. Every PNG left in the
// directory is whole (they were left truncated, under their final names), no temporary file
// is left behind, the final line counts exactly the files there as written, and the run ends
// with exit code 5 naming the overlays not written.
TEST_F(DaemonHonest, OverlaysOnAFullDiskLeaveOnlyWholePngsAndAreCounted) {
  ASSERT_TRUE(have_recording_);
  std::string why;
  const std::string disk = SmallDisk("png_disk", "128k", &why);
  if (disk.empty()) GTEST_SKIP() << why;
  const std::string png_dir = disk + "/overlays";
  std::string err;
  const int rc = testutil::Run(
      Args("file://" + (dir_ / "overlays.lcmlog").string() + "?mode=w", {"--png-dir", png_dir}),
      seconds(120), &err);
  EXPECT_EQ(rc, kExitIncomplete) << err;
  EXPECT_NE(LastLine(err).find("overlay PNGs not written"), std::string::npos) << err;

  int64_t whole = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(png_dir)) {
    const std::string name = e.path().filename().string();
    EXPECT_TRUE(std::regex_match(name, std::regex("frame_\\d{6}\\.png")))
        << "left behind: " << name;
    try {
      const core::ColorImage image = io::ReadColorPng(e.path().string());
      EXPECT_EQ(image.width, 160);
      EXPECT_EQ(image.height, 120);
      ++whole;
    } catch (const std::exception& ex) {
      ADD_FAILURE() << "a broken PNG: " << ex.what();
    }
  }
  EXPECT_GT(whole, 0);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      err, m, std::regex("overlays (\\d+) written / (\\d+) dropped / (\\d+) failed")))
      << err;
  EXPECT_EQ(std::stoll(m[1]), whole) << err;
  EXPECT_GT(std::stoll(m[3]), 0) << err;
  EXPECT_EQ(std::stoll(m[1]) + std::stoll(m[2]) + std::stoll(m[3]), 100) << err;
}

// Runs the shell command `command` (with a hang guard of 60 s); returns its exit code and its
// standard error in *err. For redirections the test helpers do not offer (> /dev/full).
int Shell(const std::string& command, const fs::path& scratch, std::string* err) {
  const fs::path err_file = scratch / "shell_stderr.txt";
  const int status =
      std::system(("timeout 60 " + command + " 2> '" + err_file.string() + "'").c_str());
  std::ifstream in(err_file);
  std::stringstream text;
  text << in.rdbuf();
  *err = text.str();
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A second YAML document is refused, naming the file and the line, with exit code 2: in the
// configuration file, and in the ROS camera_info file camera.intrinsics_file names (yaml-cpp's
// Load() read its first document and dropped the second, focal length and all, silently).
TEST_F(DaemonHonest, ASecondYamlDocumentIsRefusedNamingTheFileAndLine) {
  ASSERT_TRUE(have_recording_);
  const std::string config = (dir_ / "two_documents.yaml").string();
  WriteTextFile(config, "speed: max\n---\nlcm:\n  url: memq://\n");
  std::string err;
  int rc = testutil::Run(Args("file:///dev/null?mode=w", {"--config", config}), seconds(60), &err);
  EXPECT_EQ(rc, kExitUsage) << err;
  EXPECT_NE(LastLine(err).find(config + ":2: a second YAML document"), std::string::npos) << err;

  const std::string camera_info = (dir_ / "camera_info_two_documents.yaml").string();
  const std::string matrix = "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [";
  WriteTextFile(camera_info, "image_width: 160\nimage_height: 120\n" + matrix +
                                 "142.5, 0, 79.5, 0, 142.5, 59.5, 0, 0, 1]\n---\n" + matrix +
                                 "285, 0, 79.5, 0, 285, 59.5, 0, 0, 1]\n");
  err.clear();
  rc = testutil::Run(Args("file:///dev/null?mode=w",
                          {"--set", "camera.intrinsics_file=" + camera_info, "--max-frames", "2"}),
                     seconds(60), &err);
  EXPECT_EQ(rc, kExitUsage) << err;
  EXPECT_NE(LastLine(err).find(camera_info + ": camera_info: line 7: a second YAML document"),
            std::string::npos)
      << err;
}

// Writes `frames` depth PNGs of a box on a table (160x120) into `dir`, in TUM RGB-D's unit
// (1/5000 m) with `io::PngWriter`, and the directory's intrinsics JSON.
void WriteTumDepthDirectory(const fs::path& dir, int frames) {
  fs::create_directories(dir);
  WriteTextFile(
      (dir / "intrinsics.json").string(),
      R"({"fx": 142.5, "fy": 142.5, "cx": 79.5, "cy": 59.5, "width": 160, "height": 120})");
  core::DepthImage depth(160, 120, 0);
  for (int v = 0; v < depth.height; ++v) {
    for (int u = 0; u < depth.width; ++u) {
      // A table rising towards the top of the image (0.9 m at the bottom, 1.5 m at the top)
      // with a 10 cm box on it in the middle.
      double z_m = 1.5 - 0.6 * v / (depth.height - 1);
      if (u >= 60 && u < 100 && v >= 40 && v < 80) z_m -= 0.1;
      depth.at(u, v) = static_cast<uint16_t>(z_m * 5000.0 + 0.5);  // TUM: 5000 units per metre
    }
  }
  io::PngWriter png;
  for (int i = 0; i < frames; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "depth_%03d.png", i);
    png.WriteDepth((dir / name).string(), depth);
  }
}

// Depth PNGs in another unit (TUM RGB-D, 1/5000 m) replayed as millimetres put every point out
// of the depth range: the daemon published empty frames, exited 0 and said nothing. After 30
// frames in a row without a valid point in range it now warns, naming the likely cause and
// the keys; with camera.depth_scale_mm = 0.2 the same frames have depth and no warning comes.
TEST_F(DaemonHonest, DepthInAnotherUnitIsNamedAfterThirtyFramesWithoutValidDepth) {
  const fs::path tum = dir_ / "tum_depth";
  WriteTumDepthDirectory(tum, 40);
  const std::string log = (dir_ / "tum.lcmlog").string();
  std::string err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_DAEMON_EXE, "--source", tum.string(), "--speed", "max",
                           "--lcm-url", "file://" + log + "?mode=w"},
                          seconds(120), &err),
            kExitOk)
      << err;
  const size_t warning = err.find("warn: 30 frames in a row (up to frame 29) had no valid depth");
  ASSERT_NE(warning, std::string::npos) << err;
  const std::string line = err.substr(warning, err.find('\n', warning) - warning);
  for (const char* named : {"camera.depth_scale_mm", "0.2 for TUM", "segmenter.points.min_depth_m",
                            "segmenter.points.max_depth_m", "0.3..3 m"}) {
    EXPECT_NE(line.find(named), std::string::npos) << named << " not in: " << line;
  }
  EXPECT_EQ(err.find("had no valid depth", warning + line.size()), std::string::npos)
      << "warned once";
  std::printf("%s\n", line.c_str());

  err.clear();
  EXPECT_EQ(
      testutil::Run({CLUTTERSEG_DAEMON_EXE, "--source", tum.string(), "--speed", "max", "--lcm-url",
                     "file://" + log + "?mode=w", "--set", "camera.depth_scale_mm=0.2"},
                    seconds(120), &err),
      kExitOk)
      << err;
  EXPECT_EQ(err.find("had no valid depth"), std::string::npos) << err;
}

// Output that cannot be written is an error naming it: --print-config (and --version) to a
// full device, clutterseg-segment's --times file in a missing directory or on a full device,
// its summary to a full device.
TEST_F(DaemonHonest, OutputToAFullDeviceOrAMissingDirectoryIsAnErrorNamingIt) {
  ASSERT_TRUE(fs::exists("/dev/full")) << "no /dev/full";
  const std::string daemon = CLUTTERSEG_DAEMON_EXE;
  const std::string segment = CLUTTERSEG_SEGMENT_EXE;
  std::string err;
  EXPECT_EQ(Shell(daemon + " --print-config > /dev/full", dir_, &err), kExitFailure) << err;
  EXPECT_NE(err.find("cannot write the configuration (--print-config) to standard output: No "
                     "space left on device"),
            std::string::npos)
      << err;
  EXPECT_EQ(Shell(daemon + " --version > /dev/full", dir_, &err), kExitFailure) << err;
  EXPECT_NE(err.find("to standard output"), std::string::npos) << err;
  // The same to a file still works.
  const std::string printed = (dir_ / "config.yaml").string();
  EXPECT_EQ(Shell(daemon + " --print-config > '" + printed + "'", dir_, &err), kExitOk) << err;
  EXPECT_GT(fs::file_size(printed), 100u);

  // clutterseg-segment on a PCD the synthesizer writes.
  const fs::path pcds = dir_ / "pcds";
  ASSERT_EQ(testutil::Run({CLUTTERSEG_SYNTH_EXE, "--out", pcds.string(), "--count", "1", "--seed",
                           "3", "--width", "160", "--height", "120"},
                          seconds(120), &err),
            0)
      << err;
  const std::string pcd = (pcds / "scene_0000.pcd").string();
  const std::string missing = (dir_ / "no_such_dir" / "times.jsonl").string();
  err.clear();
  EXPECT_EQ(testutil::Run({segment, pcd, (dir_ / "a.pcd").string(), "--times", missing},
                          seconds(120), &err),
            kExitFailure);
  EXPECT_NE(err.find(missing + ": cannot open for appending: No such file or directory"),
            std::string::npos)
      << err;
  err.clear();
  EXPECT_EQ(testutil::Run({segment, pcd, (dir_ / "b.pcd").string(), "--times", "/dev/full"},
                          seconds(120), &err),
            kExitIncomplete);
  EXPECT_NE(err.find("/dev/full: write failed: No space left on device"), std::string::npos) << err;
  EXPECT_EQ(
      Shell(segment + " '" + pcd + "' '" + (dir_ / "c.pcd").string() + "' > /dev/full", dir_, &err),
      kExitIncomplete)
      << err;
  EXPECT_NE(err.find("cannot write the summary to standard output: No space left on device"),
            std::string::npos)
      << err;
}

// A directory of FRAME.PCD files (upper-case extension) is a PCD directory, for the daemon
// (it was taken for a depth-PNG directory: "no depth PNGs in ...") and for clutterseg-segment
// (it said "no .pcd or .png files").
TEST_F(DaemonHonest, UpperCasePcdFilesAreReadAsPcd) {
  std::string err;
  const fs::path pcds = dir_ / "upper_pcds";
  ASSERT_EQ(testutil::Run({CLUTTERSEG_SYNTH_EXE, "--out", pcds.string(), "--count", "2", "--seed",
                           "3", "--width", "160", "--height", "120"},
                          seconds(120), &err),
            0)
      << err;
  const fs::path upper = dir_ / "UPPER";
  fs::create_directories(upper);
  fs::copy_file(pcds / "scene_0000.pcd", upper / "FRAME_0.PCD");
  fs::copy_file(pcds / "scene_0001.pcd", upper / "FRAME_1.PCD");
  const std::string log = (dir_ / "upper.lcmlog").string();
  err.clear();
  EXPECT_EQ(testutil::Run({CLUTTERSEG_DAEMON_EXE, "--source", upper.string(), "--speed", "max",
                           "--lcm-url", "file://" + log + "?mode=w"},
                          seconds(120), &err),
            kExitOk)
      << err;
  int objects = 0;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
    objects += ev.channel == "CLUTTERSEG_OBJECTS";
  }
  EXPECT_EQ(objects, 2) << err;

  err.clear();
  const fs::path out = dir_ / "upper_out";
  EXPECT_EQ(
      testutil::Run({CLUTTERSEG_SEGMENT_EXE, upper.string(), out.string()}, seconds(120), &err),
      kExitOk)
      << err;
  EXPECT_TRUE(fs::exists(out / "FRAME_0.pcd")) << err;
  EXPECT_TRUE(fs::exists(out / "FRAME_1.pcd")) << err;
}

// A stop discards the frames still waiting in the queue (documented: "discard waiting
// frames"). The final line used to leave them out, so that a looping lockstep replay stopped
// by SIGTERM said "205 captured, 202 processed, 202 published, 0 dropped": three frames
// unaccounted for. Now every captured frame is in the line: processed, dropped or discarded.
TEST_F(DaemonHonest, FramesDiscardedByAStopAreInTheFinalLine) {
  ASSERT_TRUE(have_recording_);
  const std::string log = (dir_ / "discarded.lcmlog").string();
  // Lockstep keeps the frame queue full, so that frames are waiting when the stop comes.
  testutil::Child child = testutil::Spawn(Args("file://" + log + "?mode=w", {"--loop"}));
  ASSERT_GT(child.pid, 0);
  for (int i = 0; i < 500 && testutil::ScanLcmLog(log).events < 40; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  std::string err;
  ASSERT_EQ(testutil::Wait(&child, seconds(30), &err), kExitOk) << err;
  const int64_t captured = DoneCount(err, "captured");
  const int64_t processed = DoneCount(err, "processed");
  const int64_t dropped = DoneCount(err, "dropped");
  const int64_t discarded = std::max<int64_t>(0, DoneCount(err, "discarded at the stop"));
  ASSERT_GT(captured, 0) << err;
  std::printf("stop: %lld captured, %lld processed, %lld dropped, %lld discarded\n",
              static_cast<long long>(captured), static_cast<long long>(processed),
              static_cast<long long>(dropped), static_cast<long long>(discarded));
  EXPECT_EQ(captured, processed + dropped + discarded) << LastLine(err);
  // What the line calls published is what the log holds.
  int64_t objects = 0;
  for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
    objects += ev.channel == "CLUTTERSEG_OBJECTS" ? 1 : 0;
  }
  EXPECT_EQ(DoneCount(err, "published"), objects) << err;
}

// An output.png_dir that cannot be created (a file is in its place) is a configuration error
// named once, exit 2, before anything is published; it was an uncaught exception ("fatal",
// exit 1).
TEST_F(DaemonHonest, AnOverlayDirectoryThatCannotBeCreatedIsAConfigurationError) {
  ASSERT_TRUE(have_recording_);
  const std::string file = (dir_ / "not_a_dir").string();
  WriteTextFile(file, "x");
  const std::string log = (dir_ / "png_dir_file.lcmlog").string();
  std::string err;
  const int rc =
      testutil::Run(Args("file://" + log + "?mode=w", {"--png-dir", file}), seconds(60), &err);
  EXPECT_EQ(rc, kExitUsage) << err;
  EXPECT_NE(err.find("configuration: output.png_dir '" + file + "'"), std::string::npos) << err;
  EXPECT_EQ(err.find("fatal"), std::string::npos) << err;
  EXPECT_EQ(testutil::ScanLcmLog(log).events, 0u) << "nothing published";
}

}  // namespace
}  // namespace clutterseg::daemon
