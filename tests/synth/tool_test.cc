// Runs the clutterseg-synth executable (only built into synth_test when clutterseg_io is
// available) and checks its files and exit codes.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "tests/testing/test_data.h"
#include "tool_runner.h"

namespace clutterseg::synth {
namespace {

namespace fs = std::filesystem;

int RunTool(const std::string& args) { return testutil::RunSynthTool(args); }

std::string ReadAll(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

std::vector<std::string> ListFiles(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(SynthTool, SameSeedGivesByteIdenticalFiles) {
  const fs::path a = testing::ScratchDir("synth_tool_a");
  const fs::path b = testing::ScratchDir("synth_tool_b");
  const fs::path c = testing::ScratchDir("synth_tool_c");
  ASSERT_EQ(RunTool("--out " + a.string() + " --count 2 --seed 5 --png"), 0);
  ASSERT_EQ(RunTool("--out " + b.string() + " --count 2 --seed 5 --png --threads 2"), 0);
  ASSERT_EQ(RunTool("--out " + c.string() + " --count 2 --seed 6 --png"), 0);
  const std::vector<std::string> files = ListFiles(a);
  const std::vector<std::string> expected = {
      "intrinsics.json",      "scene_0000.pcd", "scene_0000_color.png", "scene_0000_depth.png",
      "scene_0000_label.png", "scene_0001.pcd", "scene_0001_color.png", "scene_0001_depth.png",
      "scene_0001_label.png", "scenes.json"};
  EXPECT_EQ(files, expected);
  EXPECT_EQ(ListFiles(b), files);
  for (const std::string& f : files) EXPECT_EQ(ReadAll(a / f), ReadAll(b / f)) << f;
  EXPECT_NE(ReadAll(a / "scene_0000.pcd"), ReadAll(c / "scene_0000.pcd"));

  const core::PointCloud cloud = io::ReadPcd((a / "scene_0000.pcd").string());
  EXPECT_EQ(cloud.width, 640);
  EXPECT_EQ(cloud.height, 480);
  ASSERT_TRUE(cloud.has_label());
  ASSERT_TRUE(cloud.has_color());
  const uint32_t max_label = *std::max_element(cloud.label.begin(), cloud.label.end());
  EXPECT_GE(max_label, 1u);
  EXPECT_LE(max_label, 8u);  // default object range 3..8
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (cloud.label[i] != 0) {
      ASSERT_TRUE(core::IsValid(cloud.xyz[i]));
    }
  }
  const std::string manifest = ReadAll(a / "scenes.json");
  EXPECT_NE(manifest.find("\"pcd\": \"scene_0001.pcd\""), std::string::npos);
  EXPECT_NE(manifest.find("\"seed\": 5"), std::string::npos);
  EXPECT_NE(ReadAll(a / "intrinsics.json").find("\"fx\": 525"), std::string::npos);
}

TEST(SynthTool, SequenceAndResolution) {
  const fs::path dir = testing::ScratchDir("synth_tool_seq");
  ASSERT_EQ(RunTool("--out " + dir.string() +
                    " --sequence --frames 4 --seed 3 --width 320 --height 240 --no-noise"),
            0);
  std::set<uint32_t> previous;
  for (int k = 0; k < 4; ++k) {
    const fs::path p = dir / ("scene_0000_frame_000" + std::to_string(k) + ".pcd");
    ASSERT_TRUE(fs::exists(p)) << p;
    const core::PointCloud cloud = io::ReadPcd(p.string());
    EXPECT_EQ(cloud.width, 320);
    EXPECT_EQ(cloud.height, 240);
    std::set<uint32_t> labels(cloud.label.begin(), cloud.label.end());
    labels.erase(0);
    EXPECT_LE(labels.size(), static_cast<size_t>(k));
    if (!labels.empty()) {
      EXPECT_LE(*labels.rbegin(), static_cast<uint32_t>(k));
    }
  }
}

TEST(SynthTool, ScenarioFramesKeepEveryObjectsLabel) {
  const fs::path dir = testing::ScratchDir("synth_tool_scenario");
  ASSERT_EQ(RunTool("--out " + dir.string() +
                    " --scenario remove --frames 6 --step-frames 2 --objects 4 --seed 3 "
                    "--width 320 --height 240"),
            0);
  std::vector<std::set<uint32_t>> labels;
  for (int k = 0; k < 6; ++k) {
    const fs::path p = dir / ("scene_0000_frame_000" + std::to_string(k) + ".pcd");
    ASSERT_TRUE(fs::exists(p)) << p;
    const core::PointCloud cloud = io::ReadPcd(p.string());
    std::set<uint32_t> l(cloud.label.begin(), cloud.label.end());
    l.erase(0);
    labels.push_back(l);
  }
  // One object leaves every second frame; the others keep their labels.
  EXPECT_EQ(labels[0].size(), 4u);
  for (int k = 1; k < 6; ++k) {
    EXPECT_TRUE(std::includes(labels[k - 1].begin(), labels[k - 1].end(), labels[k].begin(),
                              labels[k].end()))
        << "frame " << k;
    EXPECT_EQ(labels[k].size(), 4u - static_cast<size_t>(k / 2)) << "frame " << k;
  }
  const std::string manifest = ReadAll(dir / "scenes.json");
  EXPECT_NE(manifest.find("\"scenario\": \"remove\""), std::string::npos);
  EXPECT_NE(manifest.find("\"frame_index\": 5"), std::string::npos);

  const fs::path occ = testing::ScratchDir("synth_tool_occluder");
  ASSERT_EQ(RunTool("--out " + occ.string() +
                    " --scenario occluder --occluder box --frames 5 --objects 3 --seed 3 "
                    "--width 320 --height 240"),
            0);
  EXPECT_NE(ReadAll(occ / "scenes.json").find("\"occluder_label\": "), std::string::npos);
}

TEST(SynthTool, LabelsOnlyGroundTruthOfAPileSequenceIsByteIdenticalForASeed) {
  const fs::path a = testing::ScratchDir("synth_tool_piles_a");
  const fs::path b = testing::ScratchDir("synth_tool_piles_b");
  const std::string args =
      " --scenario piles --objects 5 --step-frames 2 --frames 24 --seed 7 --gt-labels-only "
      "--width 320 --height 240";
  ASSERT_EQ(RunTool("--out " + a.string() + args), 0);
  ASSERT_EQ(RunTool("--out " + b.string() + args + " --threads 2"), 0);
  const std::vector<std::string> files = ListFiles(a);
  ASSERT_EQ(files.size(), 25u);  // 24 label PNGs and the manifest, no PCD
  EXPECT_EQ(files.front(), "scene_0000_frame_0000_label.png");
  EXPECT_EQ(ListFiles(b), files);
  for (const std::string& f : files) EXPECT_EQ(ReadAll(a / f), ReadAll(b / f)) << f;
  const std::string manifest = ReadAll(a / "scenes.json");
  EXPECT_NE(manifest.find("\"scenario\": \"piles\""), std::string::npos);
  EXPECT_NE(manifest.find("\"centroid\": ["), std::string::npos);
  EXPECT_NE(manifest.find("\"valid_points\": "), std::string::npos);
  // The label PNG holds the first object in the first frame.
  const core::DepthImage labels = io::ReadDepthPng((a / files.front()).string());
  EXPECT_EQ(labels.width, 320);
  std::set<uint16_t> values(labels.data.begin(), labels.data.end());
  EXPECT_EQ(values, (std::set<uint16_t>{0, 1}));
  EXPECT_EQ(RunTool("--oni x.oni --gt-labels-only --scenario piles"), 2);  // needs --out
}

// --part-labels writes the same scenes with mOSD's part labels: 10 x label + part, part 1 on
// the vessels' insides (the seed's scenes hold bowls and cups).
TEST(SynthTool, PartLabelsAreTheObjectLabelsWithTheVesselInsidesApart) {
  const fs::path plain = testing::ScratchDir("synth_tool_plain");
  const fs::path parts = testing::ScratchDir("synth_tool_parts");
  const std::string args = " --count 3 --seed 2101 --objects 10:20 --png";
  ASSERT_EQ(RunTool("--out " + plain.string() + args), 0);
  ASSERT_EQ(RunTool("--out " + parts.string() + args + " --part-labels"), 0);
  int insides = 0;
  for (const char* stem : {"scene_0000", "scene_0001", "scene_0002"}) {
    const std::string pcd = std::string(stem) + ".pcd";
    const core::PointCloud a = io::ReadPcd((plain / pcd).string());
    const core::PointCloud b = io::ReadPcd((parts / pcd).string());
    ASSERT_EQ(a.size(), b.size());
    std::set<uint32_t> vessels;
    for (size_t i = 0; i < a.size(); ++i) {
      ASSERT_EQ(core::IsValid(a.xyz[i]), core::IsValid(b.xyz[i]));
      if (a.label[i] == 0) {
        ASSERT_EQ(b.label[i], 0u);
        continue;
      }
      ASSERT_EQ(b.label[i] / 10, a.label[i]);
      ASSERT_LE(b.label[i] % 10, 1u);
      if (b.label[i] % 10 == 1) {
        ++insides;
        vessels.insert(a.label[i]);
      }
    }
    // Colour and depth are the same files; the label PNG carries the part labels too.
    EXPECT_EQ(ReadAll(plain / (std::string(stem) + "_depth.png")),
              ReadAll(parts / (std::string(stem) + "_depth.png")));
    const core::DepthImage png =
        io::ReadDepthPng((parts / (std::string(stem) + "_label.png")).string());
    ASSERT_EQ(png.data.size(), b.size());
    for (size_t i = 0; i < b.size(); ++i) ASSERT_EQ(png.data[i], b.label[i]);
    EXPECT_FALSE(vessels.empty()) << stem;
  }
  EXPECT_GT(insides, 5000);
  EXPECT_EQ(RunTool("--out " + parts.string() + " --scenario piles --part-labels"), 2);
  EXPECT_EQ(RunTool("--out " + parts.string() + " --sequence --part-labels"), 2);
}

TEST(SynthTool, BadArgumentsExitTwoAndIoErrorsExitOne) {
  const fs::path dir = testing::ScratchDir("synth_tool_bad");
  const std::string out = " --out " + dir.string();
  EXPECT_EQ(RunTool(""), 2);  // --out missing
  EXPECT_EQ(RunTool(out + " --objects 5:2"), 2);
  EXPECT_EQ(RunTool(out + " --objects many"), 2);
  EXPECT_EQ(RunTool(out + " --count 0"), 2);
  EXPECT_EQ(RunTool(out + " --width 3"), 2);
  EXPECT_EQ(RunTool(out + " --noise-correlation -1"), 2);
  EXPECT_EQ(RunTool(out + " --no-such-option"), 2);
  EXPECT_EQ(RunTool(out + " --scenario shuffle"), 2);
  EXPECT_EQ(RunTool(out + " --sequence --frames 100"), 2);  // 65 at most without --scenario
  EXPECT_EQ(RunTool(out + " --scenario occluder --occluder hand"), 2);
  EXPECT_EQ(RunTool("--help"), 0);
  // The output path is an existing regular file.
  const fs::path file = dir / "not_a_dir";
  std::ofstream(file) << "x";
  EXPECT_EQ(RunTool("--out " + file.string()), 1);
  EXPECT_EQ(RunTool("--out " + (file / "sub").string()), 1);
}

}  // namespace
}  // namespace clutterseg::synth
