// clutterseg-synth --oni: the recording replays through OpenNI2's OniFile driver with the
// rendered frames (built when the tool, the ONI writer and the OpenNI2 driver exist).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/frame.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/drivers/openni2/openni2_source.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "tests/testing/test_data.h"
#include "tool_runner.h"

namespace clutterseg::synth {
namespace {

namespace fs = std::filesystem;
using testutil::RunSynthTool;

// OpenNI2 is initialized once per process, before any test runs.
class OpenNI2Environment : public ::testing::Environment {
 public:
  void SetUp() override { drivers::InitializeOpenNI2(drivers::OpenNI2Drivers::kRecordingsOnly); }
  void TearDown() override { drivers::ShutdownOpenNI2(); }
};
[[maybe_unused]] ::testing::Environment* const kOpenNI2Env =
    ::testing::AddGlobalTestEnvironment(new OpenNI2Environment);

std::string FrameStem(int k) {
  char name[32];
  std::snprintf(name, sizeof(name), "frame_%06d", k);
  return name;
}

TEST(SynthOni, RecordingReplaysTheRenderedFramesThroughOpenNI2) {
  const fs::path dir = clutterseg::testing::ScratchDir("synth_oni_replay");
  const fs::path oni = dir / "synth.oni";
  const fs::path gt = dir / "gt";
  // Two sequences of four frames: eight frames in one recording.
  ASSERT_EQ(RunSynthTool("--oni " + oni.string() + " --out " + gt.string() +
                         " --png --sequence --frames 4 --count 2 --seed 11 --width 320"
                         " --height 240 --threads 2"),
            0);
  constexpr int kFrames = 8;
  ASSERT_TRUE(fs::exists(oni));
  ASSERT_TRUE(fs::exists(gt / "scenes.json"));

  drivers::OpenNI2SourceOptions options;
  options.uri = oni.string();
  options.replay_speed = -1;  // lockstep: every frame, in order
  drivers::OpenNI2Source source(options);
  source.Open();
  EXPECT_TRUE(source.is_file());
  EXPECT_EQ(source.number_of_frames(), kFrames);
  EXPECT_NEAR(source.intrinsics().fx, 262.5, 1e-2);  // 525 scaled to 320 px
  EXPECT_EQ(source.intrinsics().width, 320);

  core::RgbdFrame frame;
  int k = 0;
  core::ReadStatus status;
  while ((status = source.Read(2000, &frame)) == core::ReadStatus::kOk && k < kFrames + 2) {
    SCOPED_TRACE("frame " + std::to_string(k));
    EXPECT_EQ(frame.sequence, static_cast<uint64_t>(k));
    EXPECT_EQ(frame.utime, static_cast<int64_t>(k) * 1000000 / 30);
    const fs::path stem = gt / FrameStem(k);
    ASSERT_TRUE(fs::exists(stem.string() + ".pcd"));
    // Depth and colour are exactly the rendered images (which the tool also wrote as PNGs).
    const core::DepthImage depth = io::ReadDepthPng(stem.string() + "_depth.png");
    const core::ColorImage color = io::ReadColorPng(stem.string() + "_color.png");
    ASSERT_EQ(frame.depth.width, 320);
    ASSERT_EQ(frame.depth.height, 240);
    EXPECT_EQ(frame.depth.data, depth.data);
    ASSERT_EQ(frame.color.data.size(), color.data.size());
    int color_mismatches = 0;
    for (size_t i = 0; i < color.data.size(); ++i) {
      const core::Rgb8 a = frame.color.data[i];
      const core::Rgb8 b = color.data[i];
      color_mismatches += (a.r != b.r || a.g != b.g || a.b != b.b) ? 1 : 0;
    }
    EXPECT_EQ(color_mismatches, 0);
    // The ground-truth cloud of the same frame number: valid exactly where the replayed depth
    // is, with the same depth.
    const core::PointCloud cloud = io::ReadPcd(stem.string() + ".pcd");
    ASSERT_EQ(cloud.size(), frame.depth.data.size());
    ASSERT_TRUE(cloud.has_label());
    int valid = 0, mismatches = 0;
    for (size_t i = 0; i < cloud.size(); ++i) {
      const uint16_t mm = frame.depth.data[i];
      if (mm == 0) {
        mismatches += std::isfinite(cloud.xyz[i].z) ? 1 : 0;
        continue;
      }
      ++valid;
      mismatches += std::lround(cloud.xyz[i].z * 1000.0f) != mm ? 1 : 0;
    }
    EXPECT_EQ(mismatches, 0);
    EXPECT_GT(valid, static_cast<int>(cloud.size()) / 2);
    ++k;
  }
  EXPECT_EQ(status, core::ReadStatus::kEndOfStream) << source.last_error();
  EXPECT_EQ(k, kFrames);
  EXPECT_FALSE(fs::exists(gt / (FrameStem(kFrames) + ".pcd")));
  source.Close();
}

TEST(SynthOni, RecordingWithoutGroundTruthAndErrors) {
  const fs::path dir = clutterseg::testing::ScratchDir("synth_oni_only");
  const fs::path oni = dir / "only.oni";
  ASSERT_EQ(RunSynthTool("--oni " + oni.string() + " --count 3 --seed 2 --width 160 --height 120"),
            0);
  drivers::OpenNI2SourceOptions options;
  options.uri = oni.string();
  options.replay_speed = -1;
  drivers::OpenNI2Source source(options);
  source.Open();
  EXPECT_EQ(source.number_of_frames(), 3);
  source.Close();
  // Nothing but the recording was written.
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) entries += e.path() != oni ? 1 : 0;
  EXPECT_EQ(entries, 0);

  EXPECT_EQ(RunSynthTool("--count 1"), 2);  // neither --out nor --oni
  EXPECT_EQ(RunSynthTool("--oni " + (dir / "missing" / "x.oni").string()), 1);
}

}  // namespace
}  // namespace clutterseg::synth
