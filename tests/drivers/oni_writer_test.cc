#include "clutterseg/drivers/oni/oni_writer.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/drivers/oni/oni_reader.h"
#include "oni_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::drivers {
namespace {

using testutil::kFramePeriodUs;

std::vector<uint8_t> ReadAll(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

void WriteAll(const std::filesystem::path& p, const std::vector<uint8_t>& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

uint64_t Le(const std::vector<uint8_t>& b, size_t at, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v |= uint64_t{b.at(at + static_cast<size_t>(i))} << (8 * i);
  return v;
}

TEST(OniWriterTest, ReaderAgreesWithWriter) {
  const auto dir = testing::ScratchDir("oni_writer_roundtrip");
  const std::string path = (dir / "rt.oni").string();
  core::CameraIntrinsics k;
  k.width = 160;
  k.height = 120;
  k.fx = 140.0;
  k.fy = 135.0;
  testutil::WriteTestOni(path, 6, /*with_color=*/true, 160, 120, k);

  OniReader reader;
  reader.Open(path);
  const OniFileInfo& info = reader.info();
  EXPECT_EQ(info.version_major, 1);
  EXPECT_EQ(info.version_minor, 0);
  EXPECT_EQ(info.version_maintenance, 1);
  EXPECT_EQ(info.version_build, 0);
  EXPECT_EQ(info.max_node_id, 2u);
  EXPECT_EQ(info.global_max_timestamp, uint64_t{5 * kFramePeriodUs});
  EXPECT_TRUE(info.has_end);
  ASSERT_EQ(info.nodes.size(), 2u);
  const OniNodeInfo& d = info.nodes[0];
  const OniNodeInfo& c = info.nodes[1];
  EXPECT_EQ(d.name, "Depth");
  EXPECT_EQ(d.type, 2u);
  EXPECT_EQ(c.name, "Image");
  EXPECT_EQ(c.type, 3u);
  for (const OniNodeInfo* n : {&d, &c}) {
    EXPECT_EQ(n->codec, "NONE");
    EXPECT_EQ(n->number_of_frames, 6u);  // NODE_ADDED patched in place
    EXPECT_EQ(n->min_timestamp_us, 0u);
    EXPECT_EQ(n->max_timestamp_us, uint64_t{5 * kFramePeriodUs});
    EXPECT_NE(n->seek_table_offset, 0u);
    EXPECT_EQ(n->seek_table_entries, 7u);
    EXPECT_EQ(n->width, 160);
    EXPECT_EQ(n->height, 120);
    EXPECT_EQ(n->fps, 30);
    EXPECT_TRUE(n->has_cropping);
    EXPECT_TRUE(n->state_ready);
    EXPECT_TRUE(n->data_begin);
    EXPECT_TRUE(n->removed);
    EXPECT_EQ(n->data_records, 6u);
    EXPECT_NEAR(n->hfov_rad, 2.0 * std::atan(160.0 / (2.0 * 140.0)), 1e-12);
    EXPECT_NEAR(n->vfov_rad, 2.0 * std::atan(120.0 / (2.0 * 135.0)), 1e-12);
    EXPECT_EQ(n->int_properties.at("xnMirror"), 0);
  }
  EXPECT_EQ(d.pixel_format, 100);
  EXPECT_EQ(c.pixel_format, 200);
  EXPECT_EQ(d.int_properties.at("oniRequiredFrameSize"), 160 * 120 * 2);
  EXPECT_EQ(c.int_properties.at("oniRequiredFrameSize"), 160 * 120 * 3);
  EXPECT_EQ(d.int_properties.at("xnDeviceMaxDepth"), 10000);
  EXPECT_EQ(c.int_properties.count("xnDeviceMaxDepth"), 0u);

  ASSERT_EQ(info.frames.size(), 12u);
  core::DepthImage depth;
  core::ColorImage color;
  for (size_t r = 0; r < info.frames.size(); ++r) {
    const OniFrameRecord& f = info.frames[r];
    const int i = static_cast<int>(r / 2);
    EXPECT_EQ(f.node_index, r % 2);
    EXPECT_EQ(f.frame_id, static_cast<uint32_t>(i + 1));
    EXPECT_EQ(f.timestamp_us, static_cast<uint64_t>(i * kFramePeriodUs));
    if (f.node_index == 0) {
      reader.ReadDepth(r, &depth);
      EXPECT_EQ(testutil::CountDepthMismatches(depth, i), 0) << "frame " << i;
      EXPECT_THROW(reader.ReadColor(r, &color), std::runtime_error);
    } else {
      reader.ReadColor(r, &color);
      EXPECT_EQ(testutil::CountColorMismatches(color, i), 0) << "frame " << i;
    }
  }

  // Seek tables: a zero entry, then (timestamp, 0, offset of the NEW_DATA record) per frame.
  const std::vector<uint8_t> bytes = ReadAll(path);
  for (size_t node = 0; node < 2; ++node) {
    const uint64_t at = info.nodes[node].seek_table_offset;
    ASSERT_EQ(Le(bytes, at + 4, 4), 0x0Eu);  // SEEK_TABLE record
    const size_t payload = at + 28;
    EXPECT_EQ(Le(bytes, payload, 8), 0u);
    EXPECT_EQ(Le(bytes, payload + 12, 8), 0u);
    for (size_t i = 0; i < 6; ++i) {
      const OniFrameRecord& f = info.frames[2 * i + node];
      const size_t e = payload + 20 * (i + 1);
      EXPECT_EQ(Le(bytes, e, 8), f.timestamp_us);
      EXPECT_EQ(Le(bytes, e + 8, 4), 0u);
      EXPECT_EQ(Le(bytes, e + 12, 8), f.record_offset);
    }
    // NEW_DATA undo positions chain to the node's previous NEW_DATA.
    for (size_t i = 0; i < 6; ++i) {
      const OniFrameRecord& f = info.frames[2 * i + node];
      const uint64_t expect_undo = i == 0 ? 0 : info.frames[2 * (i - 1) + node].record_offset;
      EXPECT_EQ(Le(bytes, f.record_offset + 20, 8), expect_undo);
    }
  }
}

TEST(OniWriterTest, DepthOnlyFileHasOneNode) {
  const auto dir = testing::ScratchDir("oni_writer_depth_only");
  const std::string path = (dir / "d.oni").string();
  testutil::WriteTestOni(path, 3, /*with_color=*/false, 64, 48);
  OniReader reader;
  reader.Open(path);
  ASSERT_EQ(reader.info().nodes.size(), 1u);
  EXPECT_EQ(reader.info().max_node_id, 1u);
  EXPECT_EQ(reader.info().frames.size(), 3u);
  core::DepthImage depth;
  reader.ReadDepth(2, &depth);
  EXPECT_EQ(testutil::CountDepthMismatches(depth, 2), 0);
}

TEST(OniWriterTest, DestructorFinalizes) {
  const auto dir = testing::ScratchDir("oni_writer_destructor");
  const std::string path = (dir / "d.oni").string();
  {
    OniWriter writer;
    writer.Open(path, 32, 24, 30, core::CameraIntrinsics{}, false);
    core::DepthImage depth;
    core::ColorImage color;
    testutil::MakeTestFrame(32, 24, 0, &depth, &color);
    writer.WriteFrame(depth, nullptr, 100);
    EXPECT_EQ(writer.frames_written(), 1);
  }
  OniReader reader;
  reader.Open(path);
  EXPECT_TRUE(reader.info().has_end);
  EXPECT_EQ(reader.info().nodes.at(0).number_of_frames, 1u);
}

TEST(OniWriterTest, RejectsBadFramesNamingTheFile) {
  const auto dir = testing::ScratchDir("oni_writer_errors");
  const std::string path = (dir / "e.oni").string();
  OniWriter writer;
  writer.Open(path, 32, 24, 30, core::CameraIntrinsics{}, true);
  core::DepthImage depth;
  core::ColorImage color;
  testutil::MakeTestFrame(32, 24, 0, &depth, &color);
  auto expect_error = [&](auto&& fn, const std::string& what) {
    try {
      fn();
      ADD_FAILURE() << "no exception for " << what;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  };
  expect_error([&] { writer.WriteFrame(depth, nullptr, 0); }, "missing colour");
  core::DepthImage small(16, 12);
  expect_error([&] { writer.WriteFrame(small, &color, 0); }, "wrong size");
  writer.WriteFrame(depth, &color, 1000);
  expect_error([&] { writer.WriteFrame(depth, &color, 999); }, "time going backwards");
  expect_error([&] { writer.WriteFrame(depth, &color, -5); }, "negative time");
  expect_error([&] { writer.Open(path, 32, 24, 30, {}, false); }, "double open");
  writer.Close();
  writer.Close();  // harmless
  EXPECT_FALSE(writer.is_open());

  OniWriter bad;
  const std::string unwritable = (dir / "no_such_dir" / "x.oni").string();
  try {
    bad.Open(unwritable, 32, 24, 30, {}, false);
    ADD_FAILURE() << "opened " << unwritable;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(unwritable), std::string::npos);
  }
  EXPECT_THROW(bad.Open((dir / "big.oni").string(), 4000, 3000, 30, {}, false), std::runtime_error);
}

TEST(OniReaderTest, RejectsGarbageAndTruncation) {
  const auto dir = testing::ScratchDir("oni_reader_hostile");
  const std::string path = (dir / "t.oni").string();
  testutil::WriteTestOni(path, 3, true, 32, 24);
  const std::vector<uint8_t> good = ReadAll(path);
  ASSERT_NO_THROW(ParseOni(good.data(), good.size(), "good"));

  std::vector<uint8_t> garbage(4096);
  std::mt19937 rng(7);
  for (uint8_t& b : garbage) b = static_cast<uint8_t>(rng());
  EXPECT_THROW(ParseOni(garbage.data(), garbage.size(), "garbage"), std::runtime_error);
  EXPECT_THROW(ParseOni(good.data(), 10, "short"), std::runtime_error);

  // Every truncation either throws or yields an unfinalized file (cut at a record boundary).
  int threw = 0;
  for (size_t len = 24; len < good.size(); len += 7) {
    try {
      const OniFileInfo info = ParseOni(good.data(), len, "truncated");
      EXPECT_FALSE(info.has_end) << len;
    } catch (const std::runtime_error&) {
      ++threw;
    }
  }
  EXPECT_GT(threw, 0);

  const auto truncated = dir / "half.oni";
  WriteAll(truncated, std::vector<uint8_t>(good.begin(), good.begin() + good.size() / 2));
  OniReader reader;
  EXPECT_THROW(reader.Open(truncated.string()), std::runtime_error);
  EXPECT_THROW(reader.Open((dir / "missing.oni").string()), std::runtime_error);
}

TEST(OniReaderTest, SurvivesRandomMutations) {
  const auto dir = testing::ScratchDir("oni_reader_mutations");
  const std::string path = (dir / "m.oni").string();
  testutil::WriteTestOni(path, 3, true, 16, 12);
  const std::vector<uint8_t> good = ReadAll(path);
  std::mt19937 rng(12345);
  int parsed = 0;
  for (int iter = 0; iter < 3000; ++iter) {
    std::vector<uint8_t> bytes = good;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) {
      const size_t at = rng() % bytes.size();
      bytes[at] = (rng() % 2 == 0) ? static_cast<uint8_t>(rng()) : 0xFF;
    }
    try {
      const OniFileInfo info = ParseOni(bytes.data(), bytes.size(), "mutated");
      ++parsed;
      for (const OniFrameRecord& fr : info.frames) {
        ASSERT_LE(fr.payload_offset + fr.payload_bytes, bytes.size());
        ASSERT_LT(fr.node_index, info.nodes.size());
      }
    } catch (const std::runtime_error&) {
    }
  }
  EXPECT_GT(parsed, 0);  // most mutations hit pixel payloads and still parse
}

TEST(OniReaderRealData, IndexesTheUnfinalizedOpenNI1Recording) {
  CLUTTERSEG_REQUIRE_DATA("oni-unfinalized/test.oni");
  const std::string path = (testing::DataDir() / "oni-unfinalized/test.oni").string();
  OniReader reader;
  reader.Open(path);
  const OniFileInfo& info = reader.info();
  EXPECT_EQ(info.version_maintenance, 0);
  EXPECT_EQ(info.version_build, 6);
  EXPECT_FALSE(info.has_end);
  EXPECT_EQ(info.max_node_id, 0xFFFFFFFFu);
  EXPECT_EQ(info.record_count, 164u);
  const OniNodeInfo* depth = info.FindNode(2);
  ASSERT_NE(depth, nullptr);
  EXPECT_EQ(depth->name, "Depth1");
  EXPECT_EQ(depth->codec, "16zT");
  EXPECT_EQ(depth->width, 320);
  EXPECT_EQ(depth->height, 240);
  EXPECT_EQ(depth->data_records, 40u);
  const OniNodeInfo* image = info.FindNode(3);
  ASSERT_NE(image, nullptr);
  EXPECT_EQ(image->data_records, 40u);
  // 16zT frames are listed but politely refused.
  const int depth_index = info.FindNodeIndex(2);
  for (size_t i = 0; i < info.frames.size(); ++i) {
    if (info.frames[i].node_index != static_cast<size_t>(depth_index)) continue;
    core::DepthImage img;
    try {
      reader.ReadDepth(i, &img);
      ADD_FAILURE() << "decoded a 16zT frame";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("16zT"), std::string::npos) << e.what();
    }
    break;
  }
}

}  // namespace
}  // namespace clutterseg::drivers
