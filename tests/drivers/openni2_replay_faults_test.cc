// Damaged and hostile recordings replayed through the real OniFile driver: files written by
// our OniWriter, then edited byte by byte (oni_mutate.h). Every frame the recording holds
// must be delivered or accounted for in report(); nothing garbled may be replayed; sizes
// beyond the frame limits and implausible fields of view are refused before anything is
// allocated. (OpenNI2 is initialised for the whole binary in openni2_source_test.cc.)

#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sys/resource.h>

#include "clutterseg/drivers/openni2/openni2_source.h"
#include "oni_mutate.h"
#include "oni_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::drivers {
namespace {

using core::ReadStatus;
using core::SkipReason;

constexpr int kFrames = 8;
constexpr int kW = 160;
constexpr int kH = 120;

// The frames of test recording `frames[i]` are frame i, in order, with the right depth; the
// colour attached to a frame, if any, is that frame's.
void ExpectTestFramesInOrder(const std::vector<core::RgbdFrame>& frames, int* with_color) {
  *with_color = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(testutil::CountDepthMismatches(frames[i].depth, static_cast<int>(i)), 0)
        << "frame " << i;
    if (!frames[i].color.empty()) {
      ++*with_color;
      EXPECT_EQ(testutil::CountColorMismatches(frames[i].color, static_cast<int>(i)), 0)
          << "frame " << i << " carries another frame's colour";
    }
  }
}

class OpenNI2ReplayFaults : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::ScratchDir("openni2_replay_faults");
    good_ = (dir_ / "good.oni").string();
    testutil::WriteTestOni(good_, kFrames, /*with_color=*/true, kW, kH);
    bytes_ = testutil::ReadFileBytes(good_);
  }

  // Writes the edited bytes as a recording of its own.
  std::string Write(const std::string& name, const std::vector<uint8_t>& bytes) {
    const std::string path = (dir_ / name).string();
    testutil::WriteFileBytes(path, bytes);
    return path;
  }

  // Replays `path` to its end (at most 4 * kFrames reads, so a bug cannot hang the test).
  std::vector<core::RgbdFrame> ReplayAll(const std::string& path, double speed,
                                         core::SourceReport* report, ReadStatus* last) {
    OpenNI2SourceOptions o;
    o.uri = path;
    o.replay_speed = speed;
    OpenNI2Source src(o);
    src.Open();
    std::vector<core::RgbdFrame> frames;
    core::RgbdFrame frame;
    *last = ReadStatus::kError;
    for (int i = 0; i < 4 * kFrames; ++i) {
      *last = src.Read(3000, &frame);
      if (*last == ReadStatus::kTimeout) continue;
      if (*last != ReadStatus::kOk) break;
      frames.push_back(frame);
    }
    *report = src.report();
    return frames;
  }

  // Replays `path` at `speed` and expects the whole recording: every frame in order, each
  // with its own colour, none counted as lost. Returns the report for further checks.
  core::SourceReport ExpectEveryFrameWithItsColour(const std::string& path, double speed) {
    core::SourceReport r;
    ReadStatus last;
    const auto frames = ReplayAll(path, speed, &r, &last);
    EXPECT_EQ(last, ReadStatus::kEndOfStream) << r.ToString();
    EXPECT_EQ(frames.size(), static_cast<size_t>(kFrames)) << r.ToString();
    int with_color = 0;
    ExpectTestFramesInOrder(frames, &with_color);
    EXPECT_EQ(with_color, kFrames);
    EXPECT_FALSE(r.lost_frames()) << r.ToString();
    return r;
  }

  // Open() must refuse `path` with a message naming it and containing `why`.
  static std::string ExpectRefused(const std::string& path, const std::string& why) {
    OpenNI2SourceOptions o;
    o.uri = path;
    o.replay_speed = -1;
    OpenNI2Source src(o);
    try {
      src.Open();
    } catch (const std::runtime_error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(path), std::string::npos) << "names the file: " << msg;
      EXPECT_NE(msg.find(why), std::string::npos) << "expected '" << why << "' in: " << msg;
      return msg;
    }
    ADD_FAILURE() << "Open() accepted " << path;
    return "";
  }

  std::filesystem::path dir_;
  std::string good_;
  std::vector<uint8_t> bytes_;
};

TEST_F(OpenNI2ReplayFaults, SoundRecordingIsFullyAccountedFor) {
  core::SourceReport r;
  ReadStatus last;
  const auto frames = ReplayAll(good_, -1, &r, &last);
  EXPECT_EQ(last, ReadStatus::kEndOfStream);
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
  int with_color = 0;
  ExpectTestFramesInOrder(frames, &with_color);
  EXPECT_EQ(with_color, kFrames);
  EXPECT_EQ(r.frames_in_source, kFrames);
  EXPECT_EQ(r.frames_delivered, static_cast<uint64_t>(kFrames));
  EXPECT_EQ(r.passes_completed, 1u);
  EXPECT_FALSE(r.lost_frames()) << r.ToString();
  EXPECT_EQ(r.frames_without_color, 0u);
  EXPECT_EQ(r.color_frames_unmatched, 0u);
  EXPECT_EQ(r.frames_empty, 0u);
}

// Colour frame ids one above the depth's (the colour node declares one more frame and no
// seek table, so that OpenNI2 accepts the ids): pairing by timestamp keeps every frame with
// its own colour. Before, frames were paired by equal ids only and none was delivered.
TEST_F(OpenNI2ReplayFaults, ColourIdsOffsetByOneStillPairEveryFrame) {
  std::vector<uint8_t> b = bytes_;
  for (const testutil::OniRecord& f : testutil::FrameRecordsOf(b, 2)) {
    testutil::SetFrameId(&b, f, static_cast<uint32_t>(testutil::GetLe(b, f.offset + 36, 4) + 1));
  }
  for (const testutil::OniRecord& r : testutil::WalkOni(b)) {
    if (r.type == 0x0D && r.node == 2) {  // NODE_ADDED "Image": numberOfFrames, seekTablePos
      const size_t fields = r.offset + 28 + 4 + 6 + 4 + 4;
      testutil::PutLe(&b, fields, kFrames + 1, 4);
      testutil::PutLe(&b, fields + 4 + 16, 0, 8);
    }
  }
  const std::string path = Write("color_ids_offset.oni", b);
  for (double speed : {-1.0, 4.0}) {
    SCOPED_TRACE(speed);
    ExpectEveryFrameWithItsColour(path, speed);
  }
}

// All depth records before all colour records: every depth frame is delivered with its own
// colour (depth and colour come from two lockstep players of the file). Before, 0 of 8
// frames were delivered.
TEST_F(OpenNI2ReplayFaults, DepthRecordsBeforeColourDeliverEveryDepthFrame) {
  std::vector<uint8_t> b = bytes_;
  testutil::DepthRecordsFirst(&b);
  const std::string path = Write("depth_first.oni", b);
  const core::SourceReport r = ExpectEveryFrameWithItsColour(path, -1);
  EXPECT_EQ(r.frames_delivered, static_cast<uint64_t>(kFrames));
  EXPECT_EQ(r.frames_without_color, 0u) << r.ToString();
}

// Every record with the same timestamp, replayed at the recorded speed: OpenNI2's own
// real-time player dropped all but a few; the source now paces a lockstep replay itself.
TEST_F(OpenNI2ReplayFaults, EqualTimestampsAtRecordedSpeedDeliverEveryFrame) {
  std::vector<uint8_t> b = bytes_;
  for (const testutil::OniRecord& r : testutil::WalkOni(b)) {
    if (r.type == testutil::kRecNewData) testutil::SetFrameTimestamp(&b, r, 0);
  }
  const std::string path = Write("equal_ts.oni", b);
  ExpectEveryFrameWithItsColour(path, 1.0);
}

// Colour missing for frames 3..5, as a live recording has when the colour camera drops
// frames (each stream numbers its own frames, so the colour ids fall 3 behind): every depth
// frame is delivered, with its own colour where there is one. A live camera with such an
// offset published nothing before.
TEST_F(OpenNI2ReplayFaults, MissingColourFramesStillDeliverEveryDepthFrame) {
  const std::string path = (dir_ / "missing_color.oni").string();
  {
    OniWriter writer;
    writer.Open(path, kW, kH, 30, core::CameraIntrinsics{}, true);
    core::DepthImage depth;
    core::ColorImage color;
    for (int i = 0; i < kFrames; ++i) {
      testutil::MakeTestFrame(kW, kH, i, &depth, &color);
      if (i >= 3 && i < 6) {
        writer.WriteDepthOnlyFrame(depth, i * testutil::kFramePeriodUs);
      } else {
        writer.WriteFrame(depth, &color, i * testutil::kFramePeriodUs);
      }
    }
  }
  core::SourceReport r;
  ReadStatus last;
  const auto frames = ReplayAll(path, -1, &r, &last);
  EXPECT_EQ(last, ReadStatus::kEndOfStream);
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames)) << r.ToString();
  int with_color = 0;
  ExpectTestFramesInOrder(frames, &with_color);
  EXPECT_EQ(with_color, kFrames - 3);
  EXPECT_EQ(r.frames_without_color, 3u) << r.ToString();
  EXPECT_FALSE(r.lost_frames()) << r.ToString();
}

// Colour records whose type lost a bit: OpenNI2's player skips them and then also loses the
// frame record that follows each one (here depth frames 5..7). Those are counted as not
// delivered, and the message says why.
TEST_F(OpenNI2ReplayFaults, UnknownRecordTypesAreCountedWithTheirCause) {
  std::vector<uint8_t> b = bytes_;
  const auto color = testutil::FrameRecordsOf(b, 2);
  for (size_t i = 3; i < 6; ++i) testutil::PutLe(&b, color[i].offset + 4, 0x1A, 4);
  const std::string path = Write("unknown_types.oni", b);
  core::SourceReport r;
  ReadStatus last;
  const auto frames = ReplayAll(path, -1, &r, &last);
  EXPECT_EQ(last, ReadStatus::kEndOfStream);
  EXPECT_EQ(r.frames_delivered + r.frames_skipped(), static_cast<uint64_t>(kFrames))
      << r.ToString();
  EXPECT_EQ(r.frames_delivered, frames.size());
  EXPECT_TRUE(r.lost_frames()) << r.ToString();
  ASSERT_FALSE(r.recent_skips.empty());
  EXPECT_NE(r.recent_skips.back().what.find("3 damaged records of unknown type"), std::string::npos)
      << r.ToString();
}

// One bit of a depth frame's record type flipped: neither our reader nor OpenNI2 sees that
// frame any more. The recording declared 8 frames: the one missing is counted as not
// delivered, naming the file (before: 7 frames and no word of the eighth).
TEST_F(OpenNI2ReplayFaults, FlippedRecordTypeBitIsCountedAsNotDelivered) {
  std::vector<uint8_t> b = bytes_;
  const auto depth = testutil::FrameRecordsOf(b, 1);
  testutil::PutLe(&b, depth[4].offset + 4, testutil::kRecNewData ^ 0x10, 4);
  const std::string path = Write("flipped_type.oni", b);
  core::SourceReport r;
  ReadStatus last;
  const auto frames = ReplayAll(path, -1, &r, &last);
  EXPECT_EQ(last, ReadStatus::kEndOfStream);
  EXPECT_EQ(frames.size(), static_cast<size_t>(kFrames - 1));
  EXPECT_EQ(r.frames_in_source, kFrames);
  EXPECT_EQ(r.frames_delivered, static_cast<uint64_t>(kFrames - 1));
  EXPECT_EQ(r.skipped_for(SkipReason::kNotDelivered), 1u) << r.ToString();
  EXPECT_TRUE(r.lost_frames());
  EXPECT_EQ(r.frames_delivered + r.frames_skipped(), static_cast<uint64_t>(r.frames_in_source));
  ASSERT_FALSE(r.recent_skips.empty());
  EXPECT_NE(r.recent_skips.back().what.find(path), std::string::npos) << r.ToString();

  // The same bit turning the record into an END: the replay stops there; the rest counted.
  std::vector<uint8_t> e = bytes_;
  testutil::PutLe(&e, depth[4].offset + 4, testutil::kRecNewData ^ 0x01, 4);
  const std::string early = Write("early_end.oni", e);
  const auto cut = ReplayAll(early, -1, &r, &last);
  EXPECT_EQ(last, ReadStatus::kEndOfStream);
  EXPECT_EQ(cut.size(), 4u);
  EXPECT_EQ(r.frames_in_source, kFrames);
  EXPECT_EQ(r.skipped_for(SkipReason::kNotDelivered), static_cast<uint64_t>(kFrames - 4))
      << r.ToString();
}

// A frame count beyond what the seek table holds (OniFile sizes its table by it).
TEST_F(OpenNI2ReplayFaults, FrameCountTheSeekTableDoesNotConfirmIsRefused) {
  std::vector<uint8_t> b = bytes_;
  for (const testutil::OniRecord& r : testutil::WalkOni(b)) {
    if (r.type == 0x0D && r.node == 1) {  // NODE_ADDED "Depth": numberOfFrames
      testutil::PutLe(&b, r.offset + 28 + 4 + 6 + 4 + 4, 0xfffffff0u, 4);
    }
  }
  ExpectRefused(Write("huge_count.oni", b),
                "declares 4294967280 frames but its seek table holds 9 entries");
}

TEST_F(OpenNI2ReplayFaults, NegativeRequiredFrameSizeIsRefused) {
  std::vector<uint8_t> b = bytes_;
  const size_t at = testutil::PropertyValueOffset(b, 1, "oniRequiredFrameSize");
  ASSERT_GT(at, 0u);
  testutil::PutLe(&b, at, static_cast<uint64_t>(-1), 8);
  const std::string msg =
      ExpectRefused(Write("negative_frame_size.oni", b), "oniRequiredFrameSize = -1");
  EXPECT_NE(msg.find("38400"), std::string::npos) << "names the size expected: " << msg;
}

// A recording declaring 16384 x 16384 px (OpenNI2 and the frame pool would have allocated
// gigabytes) is refused at Open() with the frame limit, before anything is allocated.
TEST_F(OpenNI2ReplayFaults, HugeDeclaredSizeIsRefusedBeforeAllocating) {
  for (uint32_t node : {1u, 2u}) {
    SCOPED_TRACE(node);
    std::vector<uint8_t> b = bytes_;
    const size_t at = testutil::PropertyValueOffset(b, node, "xnMapOutputMode");
    ASSERT_GT(at, 0u);
    testutil::PutLe(&b, at, 16384, 4);
    testutil::PutLe(&b, at + 4, 16384, 4);
    rusage before{};
    getrusage(RUSAGE_SELF, &before);
    ExpectRefused(Write("huge_" + std::to_string(node) + ".oni", b),
                  "16384x16384 px exceeds the frame limit of 4096x4096 px");
    rusage after{};
    getrusage(RUSAGE_SELF, &after);
    EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "KiB of peak RSS grown";
  }
}

// A declared image smaller than the stored frames would replay each frame garbled (rows of
// the wrong length): refused, naming the frame and both sizes.
TEST_F(OpenNI2ReplayFaults, DeclaredSizeSmallerThanTheStoredFramesIsRefused) {
  std::vector<uint8_t> b = bytes_;
  const size_t mode = testutil::PropertyValueOffset(b, 1, "xnMapOutputMode");
  const size_t required = testutil::PropertyValueOffset(b, 1, "oniRequiredFrameSize");
  ASSERT_GT(mode, 0u);
  ASSERT_GT(required, 0u);
  testutil::PutLe(&b, mode, kW / 2, 4);
  testutil::PutLe(&b, mode + 4, kH / 2, 4);
  testutil::PutLe(&b, required, kW / 2 * kH / 2 * 2, 8);
  ExpectRefused(Write("declared_smaller.oni", b),
                "holds 38400 bytes, but the stream declares 80x60");
}

// A 16-byte edit of xnFOV to 3.09 rad (177 degrees) would make fx about 4 px and every pixel
// a supervoxel: refused with the file and the value.
TEST_F(OpenNI2ReplayFaults, ImplausibleFieldOfViewIsRefusedNamingTheValue) {
  std::vector<uint8_t> b = bytes_;
  const size_t at = testutil::PropertyValueOffset(b, 1, "xnFOV");
  ASSERT_GT(at, 0u);
  const double hfov = 3.09;
  uint64_t bits = 0;
  std::memcpy(&bits, &hfov, 8);
  testutil::PutLe(&b, at, bits, 8);
  const std::string msg = ExpectRefused(Write("fov.oni", b), "field of view of 177.0 x");
  EXPECT_NE(msg.find("xnFOV"), std::string::npos) << msg;
  EXPECT_NE(msg.find("10..150 deg"), std::string::npos) << msg;
}

// A frame record shortened by half (its fields claim the rest, the structure stays
// consistent): refused with the frame named, never replayed half-filled.
TEST_F(OpenNI2ReplayFaults, ShortFramePayloadIsRefused) {
  std::vector<uint8_t> b = bytes_;
  const auto depth = testutil::FrameRecordsOf(b, 1);
  const testutil::OniRecord& r = depth[3];
  const uint32_t moved = r.payload_size / 2;
  testutil::PutLe(&b, r.offset + 12, r.fields_size + moved, 4);
  testutil::PutLe(&b, r.offset + 16, r.payload_size - moved, 4);
  ExpectRefused(Write("short_frame.oni", b), "frame 4 of stream 'Depth'");
}

TEST_F(OpenNI2ReplayFaults, LoopAccountsForEveryPass) {
  OpenNI2SourceOptions o;
  o.uri = good_;
  o.replay_speed = -1;
  o.loop = true;
  OpenNI2Source src(o);
  src.Open();
  core::RgbdFrame frame;
  int got = 0;
  for (int i = 0; i < 10 * kFrames && got < 2 * kFrames + 1; ++i) {
    const ReadStatus s = src.Read(3000, &frame);
    if (s == ReadStatus::kOk) ++got;
    ASSERT_NE(s, ReadStatus::kError) << src.last_error();
  }
  ASSERT_EQ(got, 2 * kFrames + 1);
  const core::SourceReport r = src.report();
  EXPECT_EQ(r.passes_completed, 2u) << r.ToString();
  EXPECT_EQ(r.frames_delivered, static_cast<uint64_t>(2 * kFrames + 1));
  EXPECT_FALSE(r.lost_frames()) << r.ToString();
  EXPECT_EQ(r.frames_without_color, 0u) << r.ToString();
}

// A recording cut while it is replayed (a copy still being written, a disk cleaned up): the
// player stops delivering, the replay ends within seconds instead of waiting forever, and
// the frames it did not deliver are counted with the reason.
TEST_F(OpenNI2ReplayFaults, RecordingCutWhileReplayingEndsAndCountsTheRest) {
  const std::string path = (dir_ / "cut_while_replaying.oni").string();
  constexpr int kLong = 24;
  testutil::WriteTestOni(path, kLong, /*with_color=*/true, 640, 480);
  OpenNI2SourceOptions o;
  o.uri = path;
  o.replay_speed = -1;
  OpenNI2Source src(o);
  src.Open();
  core::RgbdFrame frame;
  for (int i = 0; i < 3; ++i) ASSERT_EQ(src.Read(3000, &frame), ReadStatus::kOk) << i;
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 4);
  ReadStatus last = ReadStatus::kOk;
  int delivered = 3;
  for (int i = 0; i < 4 * kLong && last != ReadStatus::kEndOfStream; ++i) {
    last = src.Read(3000, &frame);
    delivered += last == ReadStatus::kOk;
    ASSERT_NE(last, ReadStatus::kError) << src.last_error();
  }
  ASSERT_EQ(last, ReadStatus::kEndOfStream) << "the replay never ended";
  const core::SourceReport r = src.report();
  EXPECT_LT(delivered, kLong);
  EXPECT_EQ(r.frames_delivered, static_cast<uint64_t>(delivered));
  EXPECT_EQ(r.frames_delivered + r.frames_skipped(), static_cast<uint64_t>(kLong)) << r.ToString();
  EXPECT_EQ(r.skipped_for(SkipReason::kNotDelivered), static_cast<uint64_t>(kLong - delivered));
  EXPECT_NE(r.ToString().find("changed while it was replayed"), std::string::npos) << r.ToString();
}

}  // namespace
}  // namespace clutterseg::drivers
