// A camera whose frames stop for seconds, on the real daemon (daemon::Daemon with its capture,
// pipeline and publisher threads, a real memq:// LCM bus): the daemon warns naming the source,
// keeps running, counts only the frames that came, takes the frames again when they resume,
// and a stop request (what SIGTERM does) during the silence ends the run at once. The camera
// is testutil::ScriptedSource (live pacing, then a gate that holds Read back), the one source
// here that can stop sending on demand. The daemon's stderr is read through a pipe while it
// runs, so each step waits for the line it expects instead of for a time.

#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "clutterseg/core/exit_codes.h"
#include "clutterseg/daemon/daemon.h"
#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/objects_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/daemon/scripted_source.h"

namespace clutterseg::daemon {
namespace {

using Clock = std::chrono::steady_clock;

// Redirects this process's stderr into a pipe for the scope; Read() returns what came so far.
class StderrPipe {
 public:
  StderrPipe() {
    std::fflush(stderr);
    saved_ = dup(2);
    if (pipe2(fds_, O_NONBLOCK | O_CLOEXEC) != 0) return;
    dup2(fds_[1], 2);
  }
  ~StderrPipe() {
    std::fflush(stderr);
    Read();
    dup2(saved_, 2);
    close(saved_);
    close(fds_[0]);
    close(fds_[1]);
    std::fprintf(stderr, "%s", text_.c_str());  // shown with the test's output
  }
  StderrPipe(const StderrPipe&) = delete;
  StderrPipe& operator=(const StderrPipe&) = delete;
  const std::string& Read() {
    char buf[4096];
    ssize_t n;
    while ((n = read(fds_[0], buf, sizeof(buf))) > 0) text_.append(buf, static_cast<size_t>(n));
    return text_;
  }
  // Waits (at most `limit`, a bound against a hang, not a measurement) until `needle` was
  // written after position `from`; returns its position or npos.
  size_t WaitFor(const std::string& needle, size_t from, std::chrono::seconds limit) {
    const auto end = Clock::now() + limit;
    while (Clock::now() < end) {
      const size_t at = Read().find(needle, from);
      if (at != std::string::npos) return at;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return std::string::npos;
  }

 private:
  int saved_{-1};
  int fds_[2]{-1, -1};
  std::string text_;
};

DaemonConfig LiveMemqConfig() {
  DaemonConfig c;
  c.lcm.url = "memq://";
  c.lcm.publish_labels = false;
  c.capture.speed = Speed::kRealtime;
  c.processing.threads = 2;
  c.status.period_s = 0.5;
  c.log_level = LogLevel::kInfo;
  return c;
}

struct Stopped {
  int exit_code{-1};
  double stop_s{0.0};  // from RequestStop to the end of the run
  DaemonStats stats;
  size_t objects_received{0};
};

// A live camera at 30 Hz that stops after 20 frames: `during` runs while the daemon waits.
Stopped RunStalledCamera(testutil::ScriptedSource** camera,
                         const std::function<void(Daemon*)>& during) {
  testutil::Script s;
  s.live = true;
  s.period_us = 33333;
  s.total_frames = -1;
  s.gate_after = 20;
  auto source = std::make_unique<testutil::ScriptedSource>(testutil::TabletopFrames(2), s);
  *camera = source.get();
  const DaemonConfig c = LiveMemqConfig();
  LcmBus bus(c.lcm.url);
  Stopped out;
  bus.Subscribe<clutterseg::objects_t>(
      c.lcm.objects_channel, [&out](const clutterseg::objects_t&) { ++out.objects_received; });
  {
    Daemon dut(c, std::move(source), &bus);
    dut.Start();
    during(&dut);
    const auto t0 = Clock::now();
    dut.RequestStop();
    EXPECT_TRUE(dut.WaitFor(std::chrono::seconds(30))) << "no end within 30 s of the stop";
    out.stop_s = std::chrono::duration<double>(Clock::now() - t0).count();
    dut.Join();
    out.exit_code = dut.exit_code();
    out.stats = dut.stats();
  }
  while (bus.Handle(0) > 0) {
  }
  return out;
}

TEST(DaemonStall, ACameraThatStopsIsNamedAndAStopDuringTheSilenceEndsAtOnce) {
  StderrPipe err;
  testutil::ScriptedSource* camera = nullptr;
  size_t warned = std::string::npos;
  const Stopped run = RunStalledCamera(&camera, [&](Daemon* d) {
    warned = err.WaitFor("no frame from scripted for", 0, std::chrono::seconds(60));
    EXPECT_EQ(d->stats().frames_captured, 20u) << "frames counted that never came";
  });
  ASSERT_NE(warned, std::string::npos) << "no warning about the silence:\n" << err.Read();
  EXPECT_NE(err.Read().find("Frames captured so far: 20", warned), std::string::npos) << err.Read();
  EXPECT_EQ(run.exit_code, kExitOk) << err.Read();
  // The documented bound of an orderly stop is 1 s; 2 s leaves room for a loaded machine.
  EXPECT_LT(run.stop_s, 2.0);
  std::printf("stop during the silence ended the run in %.3f s\n", run.stop_s);
  // Counted honestly: 20 frames came; each was segmented and published or dropped (a live
  // camera's frames are dropped when segmentation falls behind, as on a loaded machine), none
  // was left waiting after two silent seconds, and the bus got every published one.
  EXPECT_EQ(run.stats.frames_captured, 20u);
  EXPECT_EQ(run.stats.frames_processed + run.stats.frames_dropped, 20u);
  EXPECT_EQ(run.stats.frames_discarded, 0u);
  EXPECT_EQ(run.stats.frames_published, run.stats.frames_processed);
  EXPECT_EQ(run.objects_received, run.stats.frames_published);
}

TEST(DaemonStall, FramesThatResumeAreTakenAgainAndNamed) {
  StderrPipe err;
  testutil::ScriptedSource* camera = nullptr;
  size_t warned = std::string::npos, resumed = std::string::npos;
  const Stopped run = RunStalledCamera(&camera, [&](Daemon* d) {
    warned = err.WaitFor("no frame from scripted for", 0, std::chrono::seconds(60));
    if (warned == std::string::npos) return;
    camera->OpenGate();
    resumed = err.WaitFor("frames from scripted again, after", warned, std::chrono::seconds(60));
    // Keep running on the resumed frames until 30 more were published.
    const auto end = Clock::now() + std::chrono::seconds(60);
    while (d->stats().frames_published < 50 && Clock::now() < end) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  ASSERT_NE(warned, std::string::npos) << "no warning about the silence:\n" << err.Read();
  ASSERT_NE(resumed, std::string::npos) << "no note that frames came again:\n" << err.Read();
  EXPECT_EQ(run.exit_code, kExitOk) << err.Read();
  EXPECT_GE(run.stats.frames_published, 50u);
  // Every captured frame was segmented, dropped (a live camera drops when segmentation falls
  // behind) or discarded by the stop, and every segmented frame reached the bus.
  EXPECT_EQ(run.stats.frames_captured,
            run.stats.frames_processed + run.stats.frames_dropped + run.stats.frames_discarded);
  EXPECT_EQ(run.stats.frames_published, run.stats.frames_processed);
  EXPECT_EQ(run.objects_received, run.stats.frames_published);
  // One warning per silence.
  EXPECT_EQ(err.Read().find("no frame from scripted for", warned + 1), std::string::npos);
}

}  // namespace
}  // namespace clutterseg::daemon
