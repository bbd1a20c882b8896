#include "clutterseg/daemon/daemon.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <memory>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/depth_image_t.hpp"
#include "clutterseg/drivers/openni2/openni2_source.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/daemon/scripted_source.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

using std::chrono::seconds;

// Everything published on one memq bus, collected after the run.
struct Received {
  std::vector<clutterseg::objects_t> objects;
  std::vector<clutterseg::label_image_t> labels;
  std::vector<clutterseg::status_t> status;
  std::vector<clutterseg::depth_image_t> depth;  // with lcm.publish_depth
  void OnObjects(const lcm::ReceiveBuffer*, const std::string&, const clutterseg::objects_t* m) {
    objects.push_back(*m);
  }
  void OnLabels(const lcm::ReceiveBuffer*, const std::string&, const clutterseg::label_image_t* m) {
    labels.push_back(*m);
  }
  void OnStatus(const lcm::ReceiveBuffer*, const std::string&, const clutterseg::status_t* m) {
    status.push_back(*m);
  }
};

DaemonConfig MemqConfig() {
  DaemonConfig c;
  c.lcm.url = "memq://";
  c.capture.speed = Speed::kMax;
  c.processing.threads = 2;
  c.status.period_s = 0.05;
  c.log_level = LogLevel::kWarn;
  return c;
}

// Runs a daemon to completion on a memq bus and collects what it published.
struct RunResult {
  int exit_code{-1};
  std::string error;
  DaemonStats stats;
  Received got;
};

RunResult RunDaemon(const DaemonConfig& c, std::unique_ptr<core::FrameSource> source,
                    const std::function<void(Daemon*)>& during = {},
                    const std::function<void(Daemon*)>& before_start = {}) {
  LcmBus bus(c.lcm.url);
  RunResult run;
  bus.Subscribe<clutterseg::objects_t>(
      c.lcm.objects_channel,
      [&run](const clutterseg::objects_t& m) { run.got.OnObjects(nullptr, {}, &m); });
  bus.Subscribe<clutterseg::label_image_t>(
      c.lcm.labels_channel,
      [&run](const clutterseg::label_image_t& m) { run.got.OnLabels(nullptr, {}, &m); });
  bus.Subscribe<clutterseg::status_t>(c.lcm.status_channel, [&run](const clutterseg::status_t& m) {
    run.got.OnStatus(nullptr, {}, &m);
  });
  bus.Subscribe<clutterseg::depth_image_t>(
      c.lcm.depth_channel,
      [&run](const clutterseg::depth_image_t& m) { run.got.depth.push_back(m); });
  {
    Daemon dut(c, std::move(source), &bus);
    if (before_start) before_start(&dut);
    dut.Start();
    if (during) during(&dut);
    EXPECT_TRUE(dut.WaitFor(std::chrono::minutes(5))) << "the daemon did not finish";
    dut.Join();
    run.exit_code = dut.exit_code();
    run.error = dut.error();
    run.stats = dut.stats();
  }
  while (bus.Handle(0) > 0) {
  }
  return run;
}

class DaemonOni : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    oni_path_ =
        (testing::ScratchDir("daemon_oni_" + std::to_string(getpid())) / "tabletop6.oni").string();
    testutil::WriteTabletopOni(oni_path_, kFrames);
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    std::filesystem::remove_all(std::filesystem::path(oni_path_).parent_path(), ec);
  }
  std::unique_ptr<core::FrameSource> OniSource() {
    drivers::OpenNI2SourceOptions o;
    o.uri = oni_path_;
    o.replay_speed = -1;  // lockstep
    return std::make_unique<drivers::OpenNI2Source>(o);
  }
  static constexpr int kFrames = 6;
  static inline std::string oni_path_;
};

TEST_F(DaemonOni, OneObjectsMessagePerFrameInOrderWithLabelsAndStatus) {
  DaemonConfig c = MemqConfig();
  c.processing.pipeline_depth = 2;
  const RunResult run = RunDaemon(c, OniSource());
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  ASSERT_EQ(run.got.objects.size(), static_cast<size_t>(kFrames));
  ASSERT_EQ(run.got.labels.size(), static_cast<size_t>(kFrames));
  int total_objects = 0;
  for (int i = 0; i < kFrames; ++i) {
    const auto& m = run.got.objects[static_cast<size_t>(i)];
    EXPECT_EQ(m.frame_seq, i);
    EXPECT_EQ(m.camera_name, "camera");
    EXPECT_EQ(m.intrinsics.width, 640);
    EXPECT_EQ(m.num_objects, static_cast<int>(m.objects.size()));
    EXPECT_GT(m.num_valid_points, 100000);
    EXPECT_GE(m.capture_to_publish_ms, m.times.total_ms);
    total_objects += m.num_objects;
    core::LabelImage labels;
    DecodeLabelImage(run.got.labels[static_cast<size_t>(i)], &labels);
    ASSERT_EQ(labels.width, 640);
    ASSERT_EQ(labels.height, 480);
    uint32_t max_label = 0;
    for (uint32_t l : labels.data) max_label = std::max(max_label, l);
    EXPECT_EQ(max_label, static_cast<uint32_t>(m.num_objects)) << "frame " << i;
  }
  EXPECT_GT(total_objects, 0) << "tabletop frames must give objects";
  ASSERT_FALSE(run.got.status.empty());
  const auto& last = run.got.status.back();
  EXPECT_EQ(last.device_state, clutterseg::status_t::DEVICE_END_OF_STREAM);
  EXPECT_EQ(last.device_state_name, "end_of_stream");
  EXPECT_EQ(last.frames_captured, kFrames);
  EXPECT_EQ(last.frames_processed, kFrames);
  EXPECT_EQ(last.frames_dropped, 0);
  EXPECT_EQ(last.num_stages, static_cast<int>(pipeline::kNumStages));
  EXPECT_EQ(run.stats.frames_published, static_cast<uint64_t>(kFrames));
}

// Uses in-memory frames: Debian's OpenNI2 crashes when a second thread of the same process
// replays a recording after the first one has exited, so one process replays one ONI.
TEST(DaemonScripted, OutputDoesNotDependOnThreadsOrPipelineDepth) {
  auto frames = testutil::TabletopFrames(4);
  testutil::Script s;
  s.live = false;
  s.total_frames = 4;
  DaemonConfig a = MemqConfig();
  a.processing.threads = 1;
  a.processing.pipeline_depth = 1;
  DaemonConfig b = MemqConfig();
  b.processing.threads = 2;
  b.processing.pipeline_depth = 3;
  const RunResult ra = RunDaemon(a, std::make_unique<testutil::ScriptedSource>(frames, s));
  const RunResult rb = RunDaemon(b, std::make_unique<testutil::ScriptedSource>(frames, s));
  ASSERT_EQ(ra.got.objects.size(), 4u);
  ASSERT_EQ(rb.got.objects.size(), 4u);
  int total_objects = 0;
  for (size_t i = 0; i < ra.got.objects.size(); ++i) {
    const auto& x = ra.got.objects[i];
    const auto& y = rb.got.objects[i];
    EXPECT_EQ(x.frame_seq, static_cast<int64_t>(i));
    EXPECT_EQ(y.frame_seq, static_cast<int64_t>(i));
    ASSERT_EQ(x.num_objects, y.num_objects) << "frame " << i;
    total_objects += x.num_objects;
    for (size_t k = 0; k < x.objects.size(); ++k) {
      EXPECT_EQ(x.objects[k].num_points, y.objects[k].num_points);
      for (int d = 0; d < 3; ++d) EXPECT_EQ(x.objects[k].centroid[d], y.objects[k].centroid[d]);
    }
    EXPECT_EQ(ra.got.labels[i].data, rb.got.labels[i].data) << "frame " << i;
  }
  EXPECT_GT(total_objects, 0);
}

TEST(DaemonScripted, LiveSourceDropsOldestAndAccountsForEveryFrame) {
  auto frames = testutil::TabletopFrames(2);
  testutil::Script s;
  s.live = true;
  s.period_us = 1000;  // far faster than segmentation
  s.total_frames = -1;
  DaemonConfig c = MemqConfig();
  c.capture.speed = Speed::kRealtime;
  c.capture.queue_capacity = 2;
  c.capture.max_frames = 8;
  c.lcm.publish_labels = false;
  const RunResult run = RunDaemon(c, std::make_unique<testutil::ScriptedSource>(frames, s));
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  ASSERT_EQ(run.got.objects.size(), 8u);
  for (size_t i = 1; i < run.got.objects.size(); ++i) {
    EXPECT_GT(run.got.objects[i].frame_seq, run.got.objects[i - 1].frame_seq);
  }
  EXPECT_GT(run.stats.frames_dropped, 0u);
  EXPECT_GE(run.got.objects.back().frame_seq, 8);  // frames were skipped
  // Every captured frame was processed, dropped by the queue or discarded at the stop.
  EXPECT_EQ(run.stats.frames_captured,
            run.stats.frames_processed + run.stats.frames_dropped + run.stats.frames_discarded);
  EXPECT_EQ(run.stats.frames_published, 8u);
}

TEST(DaemonScripted, DeviceLossReconnectsWithBackoff) {
  auto frames = testutil::TabletopFrames(1);
  testutil::Script s;
  s.live = false;
  s.total_frames = 6;
  s.disconnect_after = 3;
  s.failed_reopens = 2;
  std::atomic<int> opens{0};
  s.opens = &opens;
  DaemonConfig c = MemqConfig();
  c.capture.reconnect_backoff_min_s = 0.01;
  c.capture.reconnect_backoff_max_s = 0.02;
  c.lcm.publish_labels = false;
  const RunResult run = RunDaemon(c, std::make_unique<testutil::ScriptedSource>(frames, s));
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  EXPECT_EQ(run.stats.reconnect_attempts, 3u);
  EXPECT_EQ(opens.load(), 4);  // Start + 2 failures + success
  ASSERT_EQ(run.got.objects.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(run.got.objects[static_cast<size_t>(i)].frame_seq, i);
  ASSERT_FALSE(run.got.status.empty());
  EXPECT_EQ(run.got.status.back().reconnect_attempts, 3);
  EXPECT_NE(run.got.status.back().last_error.find("scripted"), std::string::npos)
      << run.got.status.back().last_error;
}

TEST(DaemonScripted, SourceErrorEndsTheRunWithExitCodeOne) {
  auto frames = testutil::TabletopFrames(1);
  testutil::Script s;
  s.live = false;
  s.total_frames = 10;
  s.error_after = 2;
  DaemonConfig c = MemqConfig();
  c.lcm.publish_labels = false;
  const RunResult run = RunDaemon(c, std::make_unique<testutil::ScriptedSource>(frames, s));
  EXPECT_EQ(run.exit_code, kExitFailure);
  EXPECT_NE(run.error.find("scripted sensor fault"), std::string::npos) << run.error;
  ASSERT_FALSE(run.got.status.empty());
  EXPECT_EQ(run.got.status.back().device_state, clutterseg::status_t::DEVICE_ERROR);
  EXPECT_LE(run.got.objects.size(), 2u);
}

TEST(DaemonScripted, NewParametersApplyBetweenFrames) {
  auto frames = testutil::TabletopFrames(1);
  testutil::Script s;
  s.live = false;
  s.total_frames = 5;
  s.gate_after = 2;
  DaemonConfig c = MemqConfig();
  c.lcm.publish_labels = false;
  auto source = std::make_unique<testutil::ScriptedSource>(frames, s);
  testutil::ScriptedSource* raw = source.get();
  const RunResult run = RunDaemon(c, std::move(source), [&](Daemon* d) {
    while (d->stats().frames_published < 2)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    pipeline::SegmenterParams bad = c.segmenter;
    bad.objects.min_object_points = 0;
    EXPECT_THROW(d->UpdateSegmenterParams(bad), std::invalid_argument);
    pipeline::SegmenterParams none = c.segmenter;
    none.objects.min_object_points = 100000000;  // no segment is that large
    d->UpdateSegmenterParams(none);
    raw->OpenGate();
  });
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  ASSERT_EQ(run.got.objects.size(), 5u);
  EXPECT_GT(run.got.objects[0].num_objects, 0);
  EXPECT_EQ(run.got.objects[0].num_objects, run.got.objects[1].num_objects);
  for (size_t i = 2; i < 5; ++i) EXPECT_EQ(run.got.objects[i].num_objects, 0) << "frame " << i;
  EXPECT_EQ(run.stats.param_reloads, 1u);
}

// The depth images a run published (compressed payloads, one per frame), expecting `frames`.
std::vector<std::vector<uint8_t>> DepthPayloads(const RunResult& run, size_t frames) {
  std::vector<std::vector<uint8_t>> depths;
  for (const clutterseg::depth_image_t& m : run.got.depth) depths.push_back(m.data);
  EXPECT_EQ(depths.size(), frames);
  return depths;
}

// A reload applies between frames 2 and 3 of a still scene; the depths the daemon segmented
// (published with lcm.publish_depth) show whether the temporal filter kept its history.
std::vector<std::vector<uint8_t>> StillSceneDepthsWithReload(
    const std::function<void(pipeline::SegmenterParams*)>& change) {
  testutil::Script s;
  s.live = false;
  s.total_frames = 5;
  s.gate_after = 2;
  DaemonConfig c = MemqConfig();
  c.lcm.publish_labels = false;
  c.lcm.publish_depth = true;
  auto source = std::make_unique<testutil::ScriptedSource>(testutil::StillTabletopFrames(5), s);
  testutil::ScriptedSource* raw = source.get();
  const RunResult run = RunDaemon(c, std::move(source), [&](Daemon* d) {
    while (d->stats().frames_published < 2)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    if (change) {
      pipeline::SegmenterParams p = c.segmenter;
      change(&p);
      d->UpdateSegmenterParams(p);
    }
    raw->OpenGate();
  });
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  return DepthPayloads(run, 5);
}

TEST(DaemonScripted, AReloadKeepsTheTemporalFilterUnlessItsParametersChange) {
  const auto plain = StillSceneDepthsWithReload({});
  const auto other_keys = StillSceneDepthsWithReload(
      [](pipeline::SegmenterParams* p) { p->objects.min_object_points += 1; });
  const auto new_band = StillSceneDepthsWithReload(
      [](pipeline::SegmenterParams* p) { p->temporal.band_at_1m_m *= 1.25f; });
  const auto switched_off =
      StillSceneDepthsWithReload([](pipeline::SegmenterParams* p) { p->temporal.enabled = false; });
  ASSERT_EQ(plain.size(), 5u);
  ASSERT_EQ(other_keys.size(), 5u);
  ASSERT_EQ(new_band.size(), 5u);
  ASSERT_EQ(switched_off.size(), 5u);
  // Before the reload every run filters alike.
  EXPECT_TRUE(switched_off[1] == plain[1]);
  // Other keys reloaded: the filter and its history carry on, frame for frame.
  for (size_t k = 0; k < plain.size(); ++k) EXPECT_TRUE(other_keys[k] == plain[k]) << "frame " << k;
  // Temporal keys reloaded: a new filter, whose first frame passes unfiltered (as with the
  // filter switched off), while the running filter averages it with frames 0-1.
  EXPECT_TRUE(new_band[2] == switched_off[2]);
  EXPECT_FALSE(new_band[2] == plain[2]);
  EXPECT_FALSE(new_band[3] == switched_off[3]);  // and the new filter averages from then on
}

// A still scene whose device is lost after frame 3 and reopened: the depths segmented.
std::vector<std::vector<uint8_t>> StillSceneDepthsWithReopen(bool sequence_from_open,
                                                             bool temporal) {
  testutil::Script s;
  s.live = false;
  s.total_frames = 6;
  s.disconnect_after = 3;
  s.sequence_from_open = sequence_from_open;
  DaemonConfig c = MemqConfig();
  c.capture.reconnect_backoff_min_s = 0.01;
  c.capture.reconnect_backoff_max_s = 0.02;
  c.lcm.publish_labels = false;
  c.lcm.publish_depth = true;
  c.segmenter.temporal.enabled = temporal;
  const RunResult run =
      RunDaemon(c, std::make_unique<testutil::ScriptedSource>(testutil::StillTabletopFrames(6), s));
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  EXPECT_EQ(run.stats.reconnect_attempts, 1u);
  return DepthPayloads(run, 6);
}

TEST(DaemonScripted, AReopenedDeviceStartsTheTemporalFilterAfresh) {
  const auto raw = StillSceneDepthsWithReopen(true, false);
  const auto reopened = StillSceneDepthsWithReopen(true, true);
  const auto continued = StillSceneDepthsWithReopen(false, true);
  ASSERT_EQ(raw.size(), 6u);
  ASSERT_EQ(reopened.size(), 6u);
  ASSERT_EQ(continued.size(), 6u);
  EXPECT_FALSE(reopened[2] == raw[2]);  // filtered before the loss
  // The first frame after the reopen (sequence 0 again) has no history...
  EXPECT_TRUE(reopened[3] == raw[3]);
  EXPECT_FALSE(reopened[4] == raw[4]);  // ...and the new history starts with it
  // A source whose sequence numbers continue keeps its history across the gap.
  EXPECT_FALSE(continued[3] == raw[3]);
}

TEST(DaemonScripted, StopRequestFinishesInFlightFramesAndExitsZero) {
  auto frames = testutil::TabletopFrames(1);
  testutil::Script s;
  s.live = true;
  s.period_us = 5000;
  s.total_frames = -1;
  DaemonConfig c = MemqConfig();
  c.capture.speed = Speed::kRealtime;
  c.lcm.publish_labels = false;
  const RunResult run =
      RunDaemon(c, std::make_unique<testutil::ScriptedSource>(frames, s), [](Daemon* d) {
        while (d->stats().frames_published < 2)
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
        d->RequestStop();
      });
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  EXPECT_GE(run.got.objects.size(), 2u);
  EXPECT_EQ(run.stats.frames_published, run.got.objects.size());
  EXPECT_EQ(run.stats.frames_captured,
            run.stats.frames_processed + run.stats.frames_dropped + run.stats.frames_discarded);
}

// A stop signal between opening the source and starting the threads (the daemon attaches its
// signal handling there): the run ends at once, publishes no frame and still sends its last
// status_t.
TEST(DaemonScripted, StopBetweenOpenAndStartEndsAtOnceWithAStatus) {
  auto frames = testutil::TabletopFrames(1);
  testutil::Script s;
  s.live = true;
  s.period_us = 5000;
  s.total_frames = -1;
  DaemonConfig c = MemqConfig();
  c.capture.speed = Speed::kRealtime;
  const auto t0 = std::chrono::steady_clock::now();
  const RunResult run =
      RunDaemon(c, std::make_unique<testutil::ScriptedSource>(frames, s), {}, [](Daemon* d) {
        d->Open();
        d->RequestStop();
      });
  const double s_taken =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("stop between Open and Start: ended in %.3f s\n", s_taken);
  EXPECT_EQ(run.exit_code, kExitOk) << run.error;
  EXPECT_EQ(run.stats.frames_published, 0u);
  EXPECT_TRUE(run.got.objects.empty());
  EXPECT_FALSE(run.got.status.empty()) << "a last status_t";
}

}  // namespace
}  // namespace clutterseg::daemon
