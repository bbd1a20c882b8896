// clutterseg-segment as a process on real files: it never writes over its inputs or (without
// --force) over existing outputs, reports every failed write with a non-zero exit (a real
// full tmpfs, /dev/full), goes on past a bad input and says when no frame had a valid point.
// Exit codes: 5 (kExitIncomplete) finished with failed inputs or outputs, 1 nothing usable.

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/mount.h>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "clutterseg/pipeline/stage_times.h"
#include "tests/testing/run_process.h"
#include "tests/testing/test_data.h"

namespace clutterseg::pipeline {
namespace {

namespace fs = std::filesystem;
using testing::ProcessResult;

constexpr int kW = 160;
constexpr int kH = 120;

// A table at 1 m with a box on it, as depth in millimetres.
core::DepthImage Tabletop(int shift) {
  core::DepthImage d(kW, kH);
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      const bool box = u >= 60 + shift && u < 100 + shift && v >= 40 && v < 80;
      d.at(u, v) = static_cast<uint16_t>(box ? 850 : 1000 + v);
    }
  }
  return d;
}

core::CameraIntrinsics Intrinsics() { return core::DefaultKinectIntrinsics().Scaled(kW, kH); }

void WriteTabletopPcd(const fs::path& path, int shift) {
  core::PointCloud cloud;
  core::DepthToPointCloud(Tabletop(shift), Intrinsics(), nullptr, &cloud);
  io::WritePcd(path.string(), cloud);
}

// CRC-32 of PNG chunks (ISO 3309).
uint32_t Crc32(const std::string& data) {
  uint32_t c = 0xffffffffu;
  for (char ch : data) {
    c ^= static_cast<uint8_t>(ch);
    for (int k = 0; k < 8; ++k) c = (c & 1) != 0 ? 0xedb88320u ^ (c >> 1) : c >> 1;
  }
  return c ^ 0xffffffffu;
}

void PutBe32(std::string* s, uint32_t v) {
  for (int b = 3; b >= 0; --b) s->push_back(static_cast<char>((v >> (8 * b)) & 0xff));
}

void AppendChunk(std::string* png, const char* type, const std::string& data) {
  PutBe32(png, static_cast<uint32_t>(data.size()));
  const std::string body = std::string(type, 4) + data;
  png->append(body);
  PutBe32(png, Crc32(body));
}

// A 16-bit grey PNG header declaring `w` x `h` px with 530 kB of image data: as large as the
// file that made the tool allocate 7.5 GB before.
std::string HugeDepthPng(uint32_t w, uint32_t h) {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  PutBe32(&ihdr, w);
  PutBe32(&ihdr, h);
  ihdr += std::string("\x10\x00\x00\x00\x00", 5);
  AppendChunk(&png, "IHDR", ihdr);
  AppendChunk(&png, "IDAT", std::string(530 * 1024, '\0'));
  AppendChunk(&png, "IEND", "");
  return png;
}

std::string Name(const char* prefix, int i, const char* suffix) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%s%d%s", prefix, i, suffix);
  return buf;
}

std::string ReadText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

ProcessResult Segment(std::vector<std::string> args) {
  args.insert(args.begin(), CLUTTERSEG_SEGMENT_TOOL);
  args.push_back("--threads");
  args.push_back("1");
  const ProcessResult r = testing::RunProcess(args, std::chrono::seconds(120));
  EXPECT_FALSE(r.timed_out) << "clutterseg-segment hung";
  return r;
}

TEST(SegmentTool, RefusesToWriteOverItsInputs) {
  const fs::path dir = testing::ScratchDir("segment_tool_inputs");
  WriteTabletopPcd(dir / "a.pcd", 0);
  WriteTabletopPcd(dir / "b.pcd", 10);
  const std::string a = ReadText(dir / "a.pcd");
  const std::string b = ReadText(dir / "b.pcd");

  // The directory onto itself: every output would be an input.
  ProcessResult r = Segment({dir.string(), dir.string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("refusing to overwrite an input"), std::string::npos) << r.err;
  // One file onto itself, through "..", through a link, and as the JSON output.
  fs::create_directories(dir / "sub");
  fs::create_symlink(dir / "a.pcd", dir / "link.pcd");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{(dir / "a.pcd").string(), (dir / "a.pcd").string()},
        {(dir / "a.pcd").string(), (dir / "sub" / ".." / "a.pcd").string()},
        {(dir / "a.pcd").string(), (dir / "link.pcd").string(), "--force"},
        {(dir / "a.pcd").string(), (dir / "new.pcd").string(), "--json", (dir / "a.pcd").string(),
         "--force"}}) {
    r = Segment(args);
    EXPECT_EQ(r.exit_code, 2) << args[1] << ": " << r.err;
    EXPECT_NE(r.err.find("refusing to overwrite an input"), std::string::npos) << r.err;
  }
  // An output written twice.
  r = Segment(
      {(dir / "a.pcd").string(), (dir / "out.pcd").string(), "--png", (dir / "out.pcd").string()});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("would be written twice"), std::string::npos) << r.err;
  EXPECT_TRUE(ReadText(dir / "a.pcd") == a) << "an input was changed";
  EXPECT_TRUE(ReadText(dir / "b.pcd") == b) << "an input was changed";
  EXPECT_FALSE(fs::exists(dir / "new.pcd"));
  EXPECT_FALSE(fs::exists(dir / "out.pcd"));
}

TEST(SegmentTool, RefusesExistingOutputsWithoutForce) {
  const fs::path dir = testing::ScratchDir("segment_tool_force");
  WriteTabletopPcd(dir / "in.pcd", 0);
  const std::string out = (dir / "out.pcd").string();
  const std::string json = (dir / "out.json").string();
  ProcessResult r = Segment({(dir / "in.pcd").string(), out, "--json", json});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string first = ReadText(out);
  r = Segment({(dir / "in.pcd").string(), out, "--json", json});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("exists; use --force"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(out), std::string::npos) << r.err;
  r = Segment({(dir / "in.pcd").string(), out, "--json", json, "--force"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(ReadText(out) == first) << "the same input gives the same output";
}

// A real full file system: a 64 KiB tmpfs mounted for the test (needs root; skipped
// otherwise), and /dev/full.
class SegmentToolFullDisk : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::ScratchDir("segment_tool_full");
    full_ = dir_ / "full";
    fs::create_directories(full_);
    if (::mount("tmpfs", full_.c_str(), "tmpfs", 0, "size=64k") != 0) {
      GTEST_SKIP() << "cannot mount a tmpfs on " << full_ << ": " << std::strerror(errno)
                   << " (the full-disk test needs root)";
    }
    mounted_ = true;
    WriteTabletopPcd(dir_ / "in.pcd", 0);
  }
  void TearDown() override {
    if (mounted_) ::umount2(full_.c_str(), MNT_DETACH);
  }
  // Fills the tmpfs up to its last byte.
  void Fill() {
    std::FILE* f = std::fopen((full_ / "filler").c_str(), "wb");
    ASSERT_NE(f, nullptr);
    const std::vector<char> block(4096, 'x');
    while (std::fwrite(block.data(), 1, block.size(), f) == block.size() && std::fflush(f) == 0) {
    }
    std::fclose(f);
  }

  fs::path dir_;
  fs::path full_;
  bool mounted_{false};
};

TEST_F(SegmentToolFullDisk, EveryOutputsWriteErrorExitsNonZero) {
  const std::string in = (dir_ / "in.pcd").string();
  // The labelled cloud (384 kB) does not fit in 64 KiB: reported, and no partial file left.
  ProcessResult r = Segment({in, (full_ / "out.pcd").string()});
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find((full_ / "out.pcd").string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(full_ / "out.pcd")) << "the partly written output is removed";
  EXPECT_NE(r.out.find("\"failed\":1"), std::string::npos) << r.out;

  Fill();
  for (const char* option : {"--json", "--png", "--times"}) {
    SCOPED_TRACE(option);
    const std::string target = (full_ / (std::string(option + 2) + ".out")).string();
    r = Segment({in, (dir_ / (std::string(option + 2) + ".pcd")).string(), option, target});
    EXPECT_EQ(r.exit_code, 5) << r.err;
    EXPECT_NE(r.err.find(target), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
  }
  // /dev/full for every output at once.
  r = Segment({in, "/dev/full", "--json", (dir_ / "x.json").string()});
  EXPECT_EQ(r.exit_code, 5) << r.err;
  EXPECT_NE(r.err.find("/dev/full"), std::string::npos) << r.err;
}

TEST(SegmentTool, BadInputInADirectoryIsCountedAndTheOthersStillWritten) {
  const fs::path dir = testing::ScratchDir("segment_tool_bad_input");
  const fs::path in = dir / "in";
  fs::create_directories(in);
  for (int i = 0; i < 3; ++i) WriteTabletopPcd(in / Name("f", i, ".pcd"), 5 * i);
  const std::string f1 = ReadText(in / "f1.pcd");
  std::ofstream(in / "f1.pcd", std::ios::binary | std::ios::trunc) << f1.substr(0, f1.size() / 3);
  const ProcessResult r = Segment({in.string(), (dir / "out").string()});
  EXPECT_EQ(r.exit_code, 5) << "finished, one input missing: " << r.err;
  EXPECT_NE(r.err.find((in / "f1.pcd").string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("1 of 3 frame(s) failed"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("\"frames\":3,\"failed\":1"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(dir / "out" / "f0.pcd"));
  EXPECT_FALSE(fs::exists(dir / "out" / "f1.pcd"));
  EXPECT_TRUE(fs::exists(dir / "out" / "f2.pcd"));
  EXPECT_EQ(io::ReadPcd((dir / "out" / "f2.pcd").string()).size(), size_t{kW} * kH);
}

std::vector<std::string> Keys(const nlohmann::ordered_json& object) {
  std::vector<std::string> keys;
  for (const auto& [key, value] : object.items()) keys.push_back(key);
  return keys;
}

// The stage names of pipeline::StageTable() and "total", each followed by `suffix`.
std::vector<std::string> StageKeys(const std::string& suffix) {
  std::vector<std::string> keys;
  for (const StageInfo& info : StageTable()) keys.push_back(std::string(info.name) + suffix);
  keys.push_back("total" + suffix);
  return keys;
}

// --json, --times and the summary on stdout are JSON with their keys in their order, also for
// an input whose name is not UTF-8 (a byte that is not is written as U+FFFD).
TEST(SegmentTool, OutputsAreJsonWithTheirKeys) {
  using Json = nlohmann::ordered_json;
  using Names = std::vector<std::string>;
  const fs::path dir = testing::ScratchDir("segment_tool_json");
  const fs::path in = dir / "in\xff.pcd";
  WriteTabletopPcd(in, 0);
  const ProcessResult r =
      Segment({in.string(), (dir / "out.pcd").string(), "--json", (dir / "objects.json").string(),
               "--times", (dir / "times.jsonl").string(), "--force"});
  ASSERT_EQ(r.exit_code, 0) << r.err;

  const Json objects = Json::parse(ReadText(dir / "objects.json"));
  EXPECT_EQ(Keys(objects), (Names{"source", "width", "height", "num_valid_points",
                                  "num_supervoxels", "planes", "objects", "times_ms"}));
  EXPECT_EQ(objects["source"], (dir / "in\xef\xbf\xbd.pcd").string());
  EXPECT_EQ(objects["width"], kW);
  EXPECT_EQ(objects["height"], kH);
  ASSERT_FALSE(objects["planes"].empty());
  EXPECT_EQ(Keys(objects["planes"][0]), (Names{"id", "normal", "d", "num_points", "is_support"}));
  ASSERT_EQ(objects["objects"].size(), 1u) << "the box";
  const Json& box = objects["objects"][0];
  EXPECT_EQ(Keys(box),
            (Names{"id", "num_points", "centroid", "aabb_min", "aabb_max", "obb_center", "obb_axes",
                   "obb_extents", "support_plane_id", "mean_color", "confidence", "pixel_bbox"}));
  EXPECT_EQ(box["id"], 1);
  EXPECT_NEAR(box["centroid"][2].get<double>(), 0.85, 0.01);
  ASSERT_EQ(box["obb_axes"].size(), 3u);
  EXPECT_EQ(box["obb_axes"][2].size(), 3u);
  EXPECT_EQ(box["pixel_bbox"].size(), 4u);
  EXPECT_TRUE(box["pixel_bbox"][0].is_number_integer());
  EXPECT_EQ(Keys(objects["times_ms"]), StageKeys(""));

  const std::string times_text = ReadText(dir / "times.jsonl");
  ASSERT_EQ(std::count(times_text.begin(), times_text.end(), '\n'), 1) << "one line per frame";
  const Json times = Json::parse(times_text);
  Names times_keys = StageKeys("_ms");
  times_keys.insert(times_keys.begin(), "file");
  times_keys.push_back("objects");
  EXPECT_EQ(Keys(times), times_keys);
  EXPECT_EQ(times["file"], "in\xef\xbf\xbd.pcd");
  EXPECT_EQ(times["total_ms"], objects["times_ms"]["total"]);
  EXPECT_EQ(times["objects"], 1);

  const Json summary = Json::parse(r.out);
  EXPECT_EQ(Keys(summary), (Names{"frames", "failed", "empty", "objects", "mean_ms",
                                  "wall_ms_per_frame", "threads", "lanes"}));
  EXPECT_EQ(summary["frames"], 1);
  EXPECT_EQ(summary["failed"], 0);
  EXPECT_EQ(summary["objects"], 1);
  EXPECT_EQ(summary["mean_ms"], times["total_ms"]);
}

// A 16000 x 16000 declaration (about 530 kB of file) made the tool allocate 7.5 GB and then
// abort in the PCD writer; it is refused from the PNG header now.
TEST(SegmentTool, HugeDeclaredPngIsRefusedWithBoundedMemory) {
  const fs::path dir = testing::ScratchDir("segment_tool_huge");
  std::ofstream(dir / "huge-depth.png", std::ios::binary) << HugeDepthPng(16000, 16000);
  const ProcessResult r = Segment({(dir / "huge-depth.png").string(), (dir / "out.pcd").string()});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_LT(r.max_rss_kib, 200 * 1024) << "KiB";
  EXPECT_FALSE(fs::exists(dir / "out.pcd"));
}

// Depth that holds no point in the depth range (a wrong unit) was "segmented" into nothing
// with exit 0; now it is reported, and exit 1 when every frame is like that.
TEST(SegmentTool, NoValidPointInAnyFrameIsAnError) {
  const fs::path dir = testing::ScratchDir("segment_tool_empty");
  io::WriteDepthPng((dir / "far-depth.png").string(), core::DepthImage(640, 480, 20000));
  const ProcessResult r = Segment({(dir / "far-depth.png").string(), (dir / "out.pcd").string()});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("no valid point in the depth range"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--depth-scale"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("\"empty\":1"), std::string::npos) << r.out;
}

// An unorganized cloud (HEIGHT 1, the tabletop's valid points in a shuffled order) is
// segmented, not refused: the output has the input's layout and point order, the box's points
// carry one object label and the table's none; --png draws it through the intrinsics, and
// --png-scale 2 writes it at half size.
TEST(SegmentTool, UnorganizedCloudKeepsItsLayoutAndPointOrder) {
  const fs::path dir = testing::ScratchDir("segment_tool_unorganized");
  core::PointCloud organized;
  core::DepthToPointCloud(Tabletop(0), Intrinsics(), nullptr, &organized);
  core::PointCloud cloud;
  std::vector<uint8_t> on_box;
  for (size_t i = 0; i < organized.size(); ++i) {
    // A fixed permutation of the pixels (7919 is prime to kW * kH).
    const size_t px = (i * 7919) % organized.size();
    if (!core::IsValid(organized.xyz[px])) continue;
    cloud.xyz.push_back(organized.xyz[px]);
    on_box.push_back(organized.xyz[px].z < 0.9f ? 1 : 0);
  }
  cloud.width = static_cast<int>(cloud.xyz.size());
  cloud.height = 1;
  io::WritePcd((dir / "in.pcd").string(), cloud);
  const std::string k = (dir / "k.json").string();
  std::ofstream(k) << "{\"width\": " << kW << ", \"height\": " << kH
                   << ", \"fx\": " << Intrinsics().fx << ", \"fy\": " << Intrinsics().fy
                   << ", \"cx\": " << Intrinsics().cx << ", \"cy\": " << Intrinsics().cy << "}\n";
  const ProcessResult r =
      Segment({(dir / "in.pcd").string(), (dir / "out.pcd").string(), "--intrinsics", k, "--png",
               (dir / "out.png").string(), "--png-scale", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const core::PointCloud out = io::ReadPcd((dir / "out.pcd").string());
  ASSERT_EQ(out.width, cloud.width);
  ASSERT_EQ(out.height, 1);
  ASSERT_EQ(out.label.size(), cloud.size());
  uint32_t box_label = 0;
  size_t box = 0, table = 0, table_labelled = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_EQ(out.xyz[i].x, cloud.xyz[i].x) << i;
    ASSERT_EQ(out.xyz[i].z, cloud.xyz[i].z) << i;
    if (on_box[i]) {
      if (box_label == 0) box_label = out.label[i];
      box += out.label[i] == box_label ? 1 : 0;
    } else {
      ++table;
      table_labelled += out.label[i] != 0 ? 1 : 0;
    }
  }
  EXPECT_NE(box_label, 0u);
  EXPECT_GT(box, size_t{40} * 40 * 9 / 10);
  EXPECT_LT(table_labelled, table / 50);
  const core::ColorImage png = io::ReadColorPng((dir / "out.png").string());
  EXPECT_EQ(png.width, kW / 2);
  EXPECT_EQ(png.height, kH / 2);
}

// A bad --intrinsics file is a configuration error, as camera.intrinsics_file is for the
// daemon: exit 2 (kExitUsage) with one message naming the file and the key, before any frame
// is read and nothing written. It used to fail every frame instead (exit 1, one error per
// frame) while the daemon refused the same file with 2.
TEST(SegmentTool, BadIntrinsicsFileIsAUsageErrorNamingFileAndKey) {
  const fs::path dir = testing::ScratchDir("segment_tool_bad_intrinsics");
  WriteTabletopPcd(dir / "in.pcd", 0);
  struct Case {
    const char* name;
    const char* text;  // nullptr: the file is missing
    const char* expect;
  };
  const Case cases[] = {
      {"cx.json", R"({"fx": 525, "fy": 525, "cx": 1e30, "cy": 239.5})", "cx"},
      {"notjson.json", "fx: 525", "notjson.json"},
      {"missing.json", nullptr, "missing.json"},
  };
  for (const Case& c : cases) {
    const fs::path k = dir / c.name;
    if (c.text != nullptr) std::ofstream(k) << c.text;
    const fs::path out = dir / "out.pcd";
    const ProcessResult r =
        Segment({(dir / "in.pcd").string(), out.string(), "--intrinsics", k.string()});
    EXPECT_EQ(r.exit_code, 2) << c.name << ": " << r.err;
    EXPECT_NE(r.err.find("--intrinsics"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out)) << c.name << ": nothing is written";
  }
}

TEST(SegmentToolRealData, TumDepthNeedsItsScale) {
  CLUTTERSEG_REQUIRE_DATA("tum-frame/TUM_depth.png");
  const fs::path tum = testing::DataDir() / "tum-frame";
  const fs::path dir = testing::ScratchDir("segment_tool_tum");
  const std::vector<std::string> args = {(tum / "TUM_depth.png").string(),
                                         (dir / "out.pcd").string(), "--intrinsics",
                                         (tum / "camera_primesense.json").string(), "--force"};
  ProcessResult r = Segment(args);
  EXPECT_EQ(r.exit_code, 1) << "read as millimetres the TUM frame is 7..47 m away: " << r.err;
  EXPECT_NE(r.err.find("TUM PNGs need 0.2"), std::string::npos) << r.err;
  std::vector<std::string> scaled = args;
  scaled.push_back("--depth-scale");
  scaled.push_back("0.2");
  r = Segment(scaled);
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

}  // namespace
}  // namespace clutterseg::pipeline
