// The temporal depth filter in the `clutterseg` process: on for a recording, off with
// segmenter.temporal.enabled=false and for a directory of files, and the same output with one
// lane and one thread as with the defaults. Checked on the depth images the daemon publishes
// (lcm.publish_depth), which are the depths it segmented.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/daemon/messages.h"
#include "clutterseg/daemon/source_factory.h"
#include "clutterseg/depth_image_t.hpp"
#include "clutterseg/io/png_io.h"
#include "clutterseg/label_image_t.hpp"
#include "tests/daemon/daemon_cli.h"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

namespace fs = std::filesystem;

// What one run published, per frame in order: the depth payloads and the label images.
struct Published {
  std::vector<std::vector<uint8_t>> depth;
  std::vector<core::LabelImage> labels;
};

class DaemonTemporal : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = testing::ScratchDir("daemon_temporal_" + std::to_string(getpid()));
    recording_ = (dir_ / "static.oni").string();
    std::string err;
    have_recording_ = testutil::Run({CLUTTERSEG_SYNTH_EXE, "--scenario", "static", "--objects", "4",
                                     "--frames", "6", "--seed", "31", "--oni", recording_},
                                    std::chrono::minutes(5), &err) == 0;
    if (!have_recording_) std::fprintf(stderr, "clutterseg-synth failed: %s\n", err.c_str());
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  void SetUp() override { ASSERT_TRUE(have_recording_) << "no recording from clutterseg-synth"; }

  // Replays `source` in lockstep with depth images published, plus `extra`.
  static Published Replay(const std::string& source, const std::string& name,
                          const std::vector<std::string>& extra = {}) {
    const std::string log = (dir_ / (name + ".lcmlog")).string();
    std::vector<std::string> args = {"--set", "lcm.publish_depth=true"};
    args.insert(args.end(), extra.begin(), extra.end());
    std::string err;
    const int rc = testutil::Run(
        testutil::ReplayArgs(CLUTTERSEG_DAEMON_EXE, source, "file://" + log + "?mode=w", args),
        std::chrono::minutes(2), &err);
    EXPECT_EQ(rc, 0) << err;
    Published out;
    for (const testutil::LogEvent& ev : testutil::ReadLcmLog(log)) {
      const int size = static_cast<int>(ev.data.size());
      if (ev.channel == "CLUTTERSEG_DEPTH") {
        clutterseg::depth_image_t m;
        EXPECT_EQ(m.decode(ev.data.data(), 0, size), size);
        out.depth.push_back(m.data);
      } else if (ev.channel == "CLUTTERSEG_LABELS") {
        clutterseg::label_image_t m;
        EXPECT_EQ(m.decode(ev.data.data(), 0, size), size);
        out.labels.emplace_back();
        DecodeLabelImage(m, &out.labels.back());
      }
    }
    return out;
  }

  static inline fs::path dir_;
  static inline std::string recording_;
  static inline bool have_recording_{false};
};

TEST_F(DaemonTemporal, ARecordingIsFilteredFromItsSecondFrameOn) {
  const Published on = Replay(recording_, "on");
  const Published off = Replay(recording_, "off", {"--set", "segmenter.temporal.enabled=false"});
  ASSERT_EQ(on.depth.size(), 6u);
  ASSERT_EQ(off.depth.size(), 6u);
  EXPECT_EQ(on.depth[0], off.depth[0]);  // a first frame has no history
  for (size_t k = 1; k < on.depth.size(); ++k) EXPECT_NE(on.depth[k], off.depth[k]) << k;
}

TEST_F(DaemonTemporal, OneLaneAndOneThreadGiveTheSameFilteredFramesAndLabels) {
  const Published defaults = Replay(recording_, "defaults");
  const Published serial =
      Replay(recording_, "serial",
             {"--set", "processing.pipeline_depth=1", "--set", "processing.threads=1"});
  const Published wide = Replay(recording_, "wide", {"--set", "processing.pipeline_depth=3"});
  ASSERT_EQ(defaults.depth.size(), 6u);
  EXPECT_EQ(serial.depth, defaults.depth);
  EXPECT_EQ(wide.depth, defaults.depth);
  ASSERT_EQ(serial.labels.size(), defaults.labels.size());
  ASSERT_EQ(wide.labels.size(), defaults.labels.size());
  for (size_t k = 0; k < defaults.labels.size(); ++k) {
    EXPECT_EQ(serial.labels[k].data, defaults.labels[k].data) << k;
    EXPECT_EQ(wide.labels[k].data, defaults.labels[k].data) << k;
  }
}

// segmenter.partition runs in the ordered completion, in frame order: with it on, the
// published labels do not depend on the lanes or threads either.
TEST_F(DaemonTemporal, ThePartitionPriorGivesTheSameLabelsWhateverTheLanes) {
  const std::vector<std::string> hold = {"--set", "segmenter.partition.hold_frames=2"};
  std::vector<std::string> serial_args = hold;
  for (const char* a : {"--set", "processing.pipeline_depth=1", "--set", "processing.threads=1"}) {
    serial_args.push_back(a);
  }
  std::vector<std::string> wide_args = hold;
  wide_args.push_back("--set");
  wide_args.push_back("processing.pipeline_depth=3");
  const Published serial = Replay(recording_, "prior_serial", serial_args);
  const Published wide = Replay(recording_, "prior_wide", wide_args);
  ASSERT_EQ(serial.labels.size(), 6u);
  ASSERT_EQ(wide.labels.size(), serial.labels.size());
  for (size_t k = 0; k < serial.labels.size(); ++k) {
    EXPECT_EQ(wide.labels[k].data, serial.labels[k].data) << k;
  }
}

// At the defaults (the temporal filter and the partition hysteresis on) an object put down on
// a still table is published in the frame it appears in, as segmented: the hysteresis holds
// only still regions, and the filter resets the pixels that changed. Every object that the
// recording adds is compared, in the frame of its addition, with the same replay with the
// hysteresis off: its dominant published segment is the same size in both, and it covers
// most of the object.
TEST_F(DaemonTemporal, AnObjectPutDownShowsInTheFrameItAppearsInAtTheDefaults) {
  const std::string oni = (dir_ / "piles.oni").string();
  const fs::path gt = dir_ / "piles_gt";
  std::string err;
  ASSERT_EQ(testutil::Run({CLUTTERSEG_SYNTH_EXE, "--scenario", "piles", "--objects", "8",
                           "--step-frames", "6", "--frames", "108", "--seed", "33", "--oni", oni,
                           "--out", gt.string(), "--gt-labels-only"},
                          std::chrono::minutes(5), &err),
            0)
      << err;
  const Published held = Replay(oni, "piles_defaults");
  const Published free =
      Replay(oni, "piles_no_hold", {"--set", "segmenter.partition.hold_frames=1"});
  ASSERT_EQ(held.labels.size(), 108u);
  ASSERT_EQ(free.labels.size(), held.labels.size());
  char name[64];
  auto truth = [&](size_t k) {
    std::snprintf(name, sizeof(name), "frame_%06zu_label.png", k);
    return io::ReadDepthPng((gt / name).string());
  };
  // The published segment holding most of the pixels of label `g` in `truth`, and its size.
  struct Dominant {
    uint32_t label{0};
    size_t on_object{0};
    size_t size{0};
  };
  auto dominant = [](const core::DepthImage& truth_k, uint16_t g, const core::LabelImage& out) {
    std::vector<size_t> count;
    for (size_t i = 0; i < truth_k.data.size(); ++i) {
      const uint32_t l = out.data[i];
      if (truth_k.data[i] != g || l == 0) continue;
      if (count.size() <= l) count.resize(l + 1, 0);
      ++count[l];
    }
    Dominant d;
    for (uint32_t l = 1; l < count.size(); ++l) {
      if (count[l] > d.on_object) d = Dominant{l, count[l], 0};
    }
    for (const uint32_t l : out.data) d.size += l == d.label && d.label != 0 ? 1 : 0;
    return d;
  };
  int added = 0;
  core::DepthImage before = truth(0);
  for (size_t k = 1; k < held.labels.size(); ++k) {
    const core::DepthImage now = truth(k);
    ASSERT_EQ(now.data.size(), held.labels[k].data.size());
    std::vector<size_t> pixels(65536, 0);
    std::vector<uint8_t> seen_before(65536, 0);
    for (const uint16_t g : before.data) seen_before[g] = 1;
    for (const uint16_t g : now.data) ++pixels[g];
    for (size_t g = 1; g < pixels.size(); ++g) {
      if (seen_before[g] || pixels[g] < 200) continue;
      SCOPED_TRACE("object " + std::to_string(g) + " added in frame " + std::to_string(k));
      ++added;
      const Dominant h = dominant(now, static_cast<uint16_t>(g), held.labels[k]);
      const Dominant f = dominant(now, static_cast<uint16_t>(g), free.labels[k]);
      EXPECT_GT(h.on_object, pixels[g] / 2);
      EXPECT_EQ(h.on_object, f.on_object);
      EXPECT_EQ(h.size, f.size);
    }
    before = now;
  }
  EXPECT_GE(added, 7);  // objects 2-8 are put down on a table that has been still
  // ...while the hysteresis held the partition of still objects in some frames.
  int held_frames = 0;
  for (size_t k = 0; k < held.labels.size(); ++k) {
    held_frames += held.labels[k].data != free.labels[k].data ? 1 : 0;
  }
  EXPECT_GT(held_frames, 0);
}

TEST(DaemonTemporalSources, StreamsAreFilteredAndDirectoriesOfFilesAreNot) {
  EXPECT_TRUE(IsFrameStream("device"));
  EXPECT_TRUE(IsFrameStream("device:1d27/0601@2/3"));
  EXPECT_TRUE(IsFrameStream("synthetic"));
  EXPECT_TRUE(IsFrameStream("/recordings/run 1.oni"));
  const fs::path dir = testing::ScratchDir("temporal_sources_" + std::to_string(getpid()));
  EXPECT_FALSE(IsFrameStream(dir.string()));  // a directory: depth PNGs or PCD files
  EXPECT_FALSE(IsFrameStream((dir / "missing").string()));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace clutterseg::daemon
