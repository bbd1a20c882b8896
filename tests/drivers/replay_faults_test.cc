// Directory sources on damaged and hostile files: real PCD and PNG files written by our
// writers, then truncated, corrupted or given headers that declare huge sizes. A bad file is
// skipped, counted with its reason and name, and the replay goes on; configuration that
// would silently give wrong frames is an error.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/drivers/replay/depth_png_source.h"
#include "clutterseg/drivers/replay/pcd_directory_source.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "tests/testing/test_data.h"

namespace clutterseg::drivers {
namespace {

using core::ReadStatus;
using core::SkipReason;
namespace fs = std::filesystem;

constexpr int kW = 160;
constexpr int kH = 120;

core::DepthImage Depth(int i) {
  core::DepthImage d(kW, kH);
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) d.at(u, v) = static_cast<uint16_t>(700 + 2 * u + v + 10 * i);
  }
  return d;
}

core::CameraIntrinsics Intrinsics() { return core::DefaultKinectIntrinsics().Scaled(kW, kH); }

std::string ReadText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteText(const fs::path& p, const std::string& s) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << s;
}

void PutBigEndian(std::string* s, size_t at, uint32_t v) {
  for (int b = 0; b < 4; ++b) (*s)[at + b] = static_cast<char>((v >> (24 - 8 * b)) & 0xff);
}

// CRC-32 of PNG chunks (ISO 3309).
uint32_t Crc32(const char* data, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    c ^= static_cast<uint8_t>(data[i]);
    for (int k = 0; k < 8; ++k) c = (c & 1) != 0 ? 0xedb88320u ^ (c >> 1) : c >> 1;
  }
  return c ^ 0xffffffffu;
}

// Reads until the end; at most `max_reads` reads.
std::vector<core::RgbdFrame> ReadAll(core::FrameSource* src, int max_reads, ReadStatus* last) {
  std::vector<core::RgbdFrame> frames;
  core::RgbdFrame frame;
  for (int i = 0; i < max_reads; ++i) {
    *last = src->Read(100, &frame);
    if (*last != ReadStatus::kOk) break;
    frames.push_back(frame);
  }
  return frames;
}

// "<prefix><i><suffix>" (snprintf: GCC 12 warns about string concatenation here).
std::string Name(const char* prefix, int i, const char* suffix) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s%d%s", prefix, i, suffix);
  return buf;
}

// `s` with the first `from` replaced by `to`.
std::string Replaced(const std::string& s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  if (at == std::string::npos) return s;
  return s.substr(0, at) + to + s.substr(at + from.size());
}

// f0..f5.pcd; f1 truncated, f3 garbage, f4 declaring 100000 x 100000 points.
fs::path PcdDirectoryWithBadFiles() {
  const fs::path dir = testing::ScratchDir("replay_faults_pcd");
  for (int i = 0; i < 6; ++i) {
    core::PointCloud cloud;
    core::DepthToPointCloud(Depth(i), Intrinsics(), nullptr, &cloud);
    io::WritePcd((dir / Name("f", i, ".pcd")).string(), cloud);
  }
  const std::string f1 = ReadText(dir / "f1.pcd");
  WriteText(dir / "f1.pcd", f1.substr(0, f1.size() / 2));
  WriteText(dir / "f3.pcd", std::string(5000, '\x7f'));
  std::string f4 = ReadText(dir / "f4.pcd");
  f4 = Replaced(f4, "WIDTH 160\n", "WIDTH 100000\n");
  f4 = Replaced(f4, "HEIGHT 120\n", "HEIGHT 100000\n");
  f4 = Replaced(f4, "POINTS 19200\n", "POINTS 10000000000\n");
  WriteText(dir / "f4.pcd", f4);
  return dir;
}

// One truncated PCD used to end the whole replay; now it is skipped, counted, named.
TEST(PcdDirectoryFaults, BadFilesAreSkippedCountedAndTheReplayGoesOn) {
  const fs::path dir = PcdDirectoryWithBadFiles();
  PcdDirectorySourceOptions o;
  o.path = dir.string();
  PcdDirectorySource src(o);
  src.Open();
  ReadStatus last = ReadStatus::kError;
  const auto frames = ReadAll(&src, 20, &last);
  EXPECT_EQ(last, ReadStatus::kEndOfStream) << src.last_error();
  ASSERT_EQ(frames.size(), 3u);
  for (size_t k = 0; k < frames.size(); ++k) {
    const int i = std::vector<int>{0, 2, 5}[k];
    EXPECT_EQ(frames[k].depth.data, Depth(i).data) << "frame " << k << " is f" << i;
    EXPECT_EQ(frames[k].sequence, k);
  }
  const core::SourceReport r = src.report();
  EXPECT_EQ(r.frames_in_source, 6);
  EXPECT_EQ(r.frames_delivered, 3u);
  EXPECT_EQ(r.skipped_for(SkipReason::kUnreadable), 2u) << r.ToString();
  EXPECT_EQ(r.skipped_for(SkipReason::kTooLarge), 1u) << r.ToString();
  EXPECT_EQ(r.frames_delivered + r.frames_skipped(), 6u);
  EXPECT_EQ(r.passes_completed, 1u);
  ASSERT_EQ(r.recent_skips.size(), 3u);
  EXPECT_NE(r.recent_skips[0].what.find("f1.pcd"), std::string::npos) << r.ToString();
  EXPECT_NE(r.recent_skips[0].what.find("truncated"), std::string::npos) << r.ToString();
  EXPECT_NE(r.recent_skips[1].what.find("f3.pcd"), std::string::npos) << r.ToString();
  EXPECT_NE(r.recent_skips[2].what.find("f4.pcd"), std::string::npos) << r.ToString();
  EXPECT_NE(r.recent_skips[2].what.find("exceed"), std::string::npos) << r.ToString();
  EXPECT_EQ(r.recent_skips[2].serial, 3u);
}

// The first file is the bad one: the intrinsics come from the first readable file.
TEST(PcdDirectoryFaults, FirstFileUnreadableStillOpensAndLoops) {
  const fs::path dir = testing::ScratchDir("replay_faults_pcd_first");
  for (int i = 0; i < 3; ++i) {
    core::PointCloud cloud;
    core::DepthToPointCloud(Depth(i), Intrinsics(), nullptr, &cloud);
    io::WritePcd((dir / Name("f", i, ".pcd")).string(), cloud);
  }
  const std::string f0 = ReadText(dir / "f0.pcd");
  WriteText(dir / "f0.pcd", f0.substr(0, 100));
  PcdDirectorySourceOptions o;
  o.path = dir.string();
  o.loop = true;
  PcdDirectorySource src(o);
  src.Open();
  EXPECT_NEAR(src.intrinsics().fx, Intrinsics().fx, 0.01);
  core::RgbdFrame frame;
  for (int n = 0; n < 5; ++n) ASSERT_EQ(src.Read(100, &frame), ReadStatus::kOk);
  const core::SourceReport r = src.report();
  EXPECT_EQ(r.frames_delivered, 5u);
  EXPECT_EQ(r.skipped_for(SkipReason::kUnreadable), 3u) << r.ToString();  // once per pass
}

TEST(PcdDirectoryFaults, LoopingDirectoryWithoutAReadableFileIsAnErrorNotAHang) {
  const fs::path dir = testing::ScratchDir("replay_faults_pcd_none");
  WriteText(dir / "a.pcd", "garbage");
  WriteText(dir / "b.pcd", "more garbage");
  PcdDirectorySourceOptions o;
  o.path = dir.string();
  o.loop = true;
  o.estimate_intrinsics = false;
  PcdDirectorySource src(o);
  src.Open();
  core::RgbdFrame frame;
  EXPECT_EQ(src.Read(100, &frame), ReadStatus::kError);
  EXPECT_NE(src.last_error().find(dir.string()), std::string::npos) << src.last_error();
  EXPECT_EQ(src.report().skipped_for(SkipReason::kUnreadable), 2u);
  // Without a readable organized cloud no intrinsics can be fitted: refused at Open().
  o.estimate_intrinsics = true;
  PcdDirectorySource fitting(o);
  try {
    fitting.Open();
    ADD_FAILURE() << "opened a directory without a readable cloud";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("give the intrinsics explicitly"), std::string::npos)
        << e.what();
  }
}

TEST(PcdDirectoryFaults, FramesWithoutAFinitePointAreCountedEmpty) {
  const fs::path dir = testing::ScratchDir("replay_faults_pcd_empty");
  for (int i = 0; i < 3; ++i) {
    core::PointCloud cloud;
    core::DepthToPointCloud(core::DepthImage(kW, kH, 0), Intrinsics(), nullptr, &cloud);
    io::WritePcd((dir / Name("e", i, ".pcd")).string(), cloud);
  }
  PcdDirectorySourceOptions o;
  o.path = dir.string();
  o.estimate_intrinsics = false;
  o.intrinsics = Intrinsics();
  PcdDirectorySource src(o);
  src.Open();
  ReadStatus last = ReadStatus::kError;
  EXPECT_EQ(ReadAll(&src, 10, &last).size(), 3u);
  const core::SourceReport r = src.report();
  EXPECT_EQ(r.frames_empty, 3u);
  EXPECT_TRUE(r.all_empty()) << r.ToString();
}

// A second *.json beside the PNGs silently replaced the intrinsics with the Kinect defaults;
// now it is an error naming both files, and intrinsics_json chooses.
TEST(DepthPngFaults, TwoIntrinsicsFilesAreAnErrorNamingBoth) {
  const fs::path dir = testing::ScratchDir("replay_faults_png_json");
  io::WriteDepthPng((dir / "0-depth.png").string(), Depth(0));
  const std::string json =
      R"({"fx": 300, "fy": 301, "cx": 80, "cy": 60, "width": 160, "height": 120})";
  WriteText(dir / "camera.json", json);
  WriteText(dir / "other.json", json);
  DepthPngSourceOptions o;
  o.directory = dir.string();
  DepthPngSource src(o);
  try {
    src.Open();
    ADD_FAILURE() << "opened with two intrinsics files";
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find((dir / "camera.json").string()), std::string::npos) << msg;
    EXPECT_NE(msg.find((dir / "other.json").string()), std::string::npos) << msg;
    EXPECT_NE(msg.find("intrinsics_json"), std::string::npos) << msg;
  }
  o.intrinsics_json = (dir / "other.json").string();
  DepthPngSource chosen(o);
  chosen.Open();
  EXPECT_DOUBLE_EQ(chosen.intrinsics().fx, 300.0);
}

TEST(DepthPngFaults, BadPngsAreSkippedCountedAndColourProblemsLeaveDepthAlone) {
  const fs::path dir = testing::ScratchDir("replay_faults_png");
  for (int i = 0; i < 5; ++i) {
    io::WriteDepthPng((dir / Name("", i, "-depth.png")).string(), Depth(i));
  }
  io::WriteColorPng((dir / "0-color.png").string(), core::ColorImage(kW, kH, {1, 2, 3}));
  io::WriteColorPng((dir / "2-color.png").string(), core::ColorImage(kW / 2, kH, {1, 2, 3}));
  const std::string d1 = ReadText(dir / "1-depth.png");
  WriteText(dir / "1-depth.png", d1.substr(0, d1.size() / 2));
  // 3-depth.png declares 30000 x 30000 px (IHDR width and height, with a valid CRC).
  std::string d3 = ReadText(dir / "3-depth.png");
  PutBigEndian(&d3, 16, 30000);
  PutBigEndian(&d3, 20, 30000);
  PutBigEndian(&d3, 29, Crc32(d3.data() + 12, 17));
  WriteText(dir / "3-depth.png", d3);
  DepthPngSourceOptions o;
  o.directory = dir.string();
  o.intrinsics = Intrinsics();
  DepthPngSource src(o);
  src.Open();
  ReadStatus last = ReadStatus::kError;
  const auto frames = ReadAll(&src, 20, &last);
  EXPECT_EQ(last, ReadStatus::kEndOfStream) << src.last_error();
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].depth.data, Depth(0).data);
  EXPECT_EQ(frames[0].color.width, kW);
  EXPECT_EQ(frames[1].depth.data, Depth(2).data);
  EXPECT_TRUE(frames[1].color.empty()) << "colour of another size is left out";
  EXPECT_EQ(frames[2].depth.data, Depth(4).data);
  const core::SourceReport r = src.report();
  EXPECT_EQ(r.frames_in_source, 5);
  EXPECT_EQ(r.frames_delivered, 3u);
  EXPECT_EQ(r.frames_without_color, 1u) << r.ToString();
  EXPECT_EQ(r.skipped_for(SkipReason::kUnreadable), 1u) << r.ToString();
  EXPECT_EQ(r.skipped_for(SkipReason::kTooLarge), 1u) << r.ToString();
  ASSERT_EQ(r.recent_skips.size(), 2u);
  EXPECT_NE(r.recent_skips[0].what.find("1-depth.png"), std::string::npos) << r.ToString();
  EXPECT_NE(r.recent_skips[1].what.find("3-depth.png"), std::string::npos) << r.ToString();
  EXPECT_NE(r.recent_skips[1].what.find("30000x30000 px exceeds the frame limit"),
            std::string::npos)
      << r.ToString();
}

// Depth at another aspect ratio than the intrinsics cannot be scaled to them: skipped.
TEST(DepthPngFaults, AnotherAspectRatioThanTheIntrinsicsIsSkipped) {
  const fs::path dir = testing::ScratchDir("replay_faults_png_aspect");
  io::WriteDepthPng((dir / "0-depth.png").string(), Depth(0));
  io::WriteDepthPng((dir / "1-depth.png").string(), core::DepthImage(kW, kW, 900));
  DepthPngSourceOptions o;
  o.directory = dir.string();
  o.intrinsics = Intrinsics();
  DepthPngSource src(o);
  src.Open();
  ReadStatus last = ReadStatus::kError;
  EXPECT_EQ(ReadAll(&src, 10, &last).size(), 1u);
  const core::SourceReport r = src.report();
  EXPECT_EQ(r.skipped_for(SkipReason::kSizeMismatch), 1u) << r.ToString();
  ASSERT_FALSE(r.recent_skips.empty());
  EXPECT_NE(r.recent_skips.back().what.find("another aspect ratio"), std::string::npos);
}

// TUM depth is value / 5000 m: read with the TUM scale it is the metres TUM documents; the
// frames are never empty either way, so a wrong scale shows only downstream (see the
// clutterseg-segment test), which is why the scale is an explicit option.
TEST(DepthPngFaultsRealData, TumFrameWithItsDepthScale) {
  CLUTTERSEG_REQUIRE_DATA("tum-frame/TUM_depth.png");
  DepthPngSourceOptions o;
  o.directory = (testing::DataDir() / "tum-frame").string();
  o.depth_scale_to_mm = 0.2;
  DepthPngSource src(o);
  src.Open();
  core::RgbdFrame frame;
  ASSERT_EQ(src.Read(100, &frame), ReadStatus::kOk) << src.last_error();
  uint16_t lo = 65535;
  for (uint16_t d : frame.depth.data) {
    if (d != 0) lo = std::min(lo, d);
  }
  EXPECT_GT(lo, 1000);  // the nearest point of the TUM frame is about 1.46 m away
  EXPECT_LT(lo, 2000);
  EXPECT_EQ(src.report().frames_empty, 0u);
}

}  // namespace
}  // namespace clutterseg::drivers
