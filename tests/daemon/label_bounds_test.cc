// Hostile label_image_t, objects_t and status_t messages: DecodeLabelImage refuses sizes
// beyond the frame limits and run lengths that do not cover the image before it allocates,
// and clutterseg-listen checks every message against its own length before lcm-gen's decoder
// allocates what the message declares.

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/status_t.hpp"
#include "tests/testing/run_process.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

namespace fs = std::filesystem;

void PutRun(uint16_t label, uint32_t run, std::vector<uint8_t>* data) {
  data->push_back(static_cast<uint8_t>(label & 0xff));
  data->push_back(static_cast<uint8_t>(label >> 8));
  for (int i = 0; i < 4; ++i) data->push_back(static_cast<uint8_t>(run >> (8 * i)));
}

// A label image of `w` x `h` as RLE runs of at most 2^32 - 1 pixels: about 100 bytes for
// the largest image a label_image_t can declare.
clutterseg::label_image_t RleImage(int w, int h) {
  clutterseg::label_image_t m{};
  m.camera_name = std::string(1, 'c');
  m.width = w;
  m.height = h;
  m.compression = clutterseg::label_image_t::COMPRESSION_RLE;
  uint64_t left = static_cast<uint64_t>(w) * static_cast<uint64_t>(h);
  while (left > 0) {
    const uint32_t run = static_cast<uint32_t>(std::min<uint64_t>(left, 16u << 20));
    PutRun(1, run, &m.data);
    left -= run;
  }
  m.size = static_cast<int32_t>(m.data.size());
  return m;
}

// Before: 16384 x 16384 was accepted (up to 2^28 px) and cost 1 GiB of labels, then 768 MiB
// of overlay in clutterseg-listen.
TEST(LabelImageBounds, SizesBeyondTheFrameLimitsAreRefusedBeforeAllocating) {
  core::LabelImage out;
  const long before = testing::PeakRssKib();
  const clutterseg::label_image_t huge = RleImage(16384, 16384);
  EXPECT_LT(huge.data.size(), 200u);
  try {
    DecodeLabelImage(huge, &out);
    ADD_FAILURE() << "decoded a 16384x16384 label image";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("16384x16384 px exceeds the frame limit"),
              std::string::npos)
        << e.what();
  }
  EXPECT_LT(testing::PeakRssKib() - before, 64 * 1024) << "KiB of peak RSS grown";
  // The largest image within the limits decodes.
  DecodeLabelImage(RleImage(4096, 4096), &out);
  EXPECT_EQ(out.width, 4096);
  EXPECT_EQ(out.at(4095, 4095), 1u);
}

TEST(LabelImageBounds, RunsAndStreamsThatCannotHoldTheImageAreRefused) {
  core::LabelImage out;
  clutterseg::label_image_t m = RleImage(64, 48);
  m.data.clear();
  PutRun(1, 64 * 48 - 1, &m.data);  // one pixel short
  m.size = static_cast<int32_t>(m.data.size());
  EXPECT_THROW(DecodeLabelImage(m, &out), std::runtime_error);
  m.data.clear();
  PutRun(1, 0xffffffffu, &m.data);  // far beyond the image
  m.size = static_cast<int32_t>(m.data.size());
  EXPECT_THROW(DecodeLabelImage(m, &out), std::runtime_error);
  // zlib cannot inflate 10 bytes into a 4096 x 4096 image.
  m.width = 4096;
  m.height = 4096;
  m.compression = clutterseg::label_image_t::COMPRESSION_ZLIB;
  m.data.assign(10, 0x78);
  m.size = 10;
  try {
    DecodeLabelImage(m, &out);
    ADD_FAILURE() << "accepted 10 zlib bytes for 4096x4096 labels";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot hold"), std::string::npos) << e.what();
  }
  m.width = -1;
  EXPECT_THROW(DecodeLabelImage(m, &out), std::runtime_error);
  // An empty frame is not an error.
  clutterseg::label_image_t empty{};
  DecodeLabelImage(empty, &out);
  EXPECT_TRUE(out.data.empty());
}

// Big-endian int32 at `at` of an encoded message.
void PutBe32(std::vector<uint8_t>* b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) (*b)[at + i] = static_cast<uint8_t>(v >> (24 - 8 * i));
}

template <typename Message>
std::vector<uint8_t> Encode(const Message& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  return b;
}

// A log with hostile messages (each a few dozen bytes declaring gigabytes), then two good
// frames: clutterseg-listen rejects the hostile ones naming the problem, keeps its memory
// bounded, writes the good frames' PNGs and exits 5 (incomplete).
TEST(ListenBounds, HostileMessagesAreRejectedWithBoundedMemory) {
  const fs::path dir = testing::ScratchDir("listen_bounds");
  const std::string log = (dir / "hostile.lcmlog").string();
  {
    LcmBus bus("file://" + log + "?mode=w");
    // label_image_t declaring 2^31 - 1 bytes of data (lcm-gen's decoder allocated them).
    clutterseg::label_image_t l{};
    l.camera_name = std::string(1, 'c');
    std::vector<uint8_t> b = Encode(l);
    PutBe32(&b, 8 + 8 + 8 + 8 + 4 + 2 + 4 + 4 + 1, 0x7fffffffu);
    bus.Publish("CLUTTERSEG_LABELS", b.data(), b.size());
    // A well-formed label image of 16384 x 16384 px in about 100 bytes of runs.
    const clutterseg::label_image_t huge = RleImage(16384, 16384);
    bus.PublishMessage("CLUTTERSEG_LABELS", huge);
    // objects_t declaring 10^8 planes, status_t declaring 2^28 stages, a negative string.
    clutterseg::objects_t o{};
    o.camera_name = std::string(1, 'c');
    b = Encode(o);
    // Hash, times, camera_name "c", intrinsics, frame_id "", the camera's pose.
    PutBe32(&b, 8 + 8 + 8 + 8 + 4 + 2 + 40 + 4 + 1 + 7 * 8, 100000000u);
    bus.Publish("CLUTTERSEG_OBJECTS", b.data(), b.size());
    b = Encode(o);
    PutBe32(&b, 8 + 8 + 8 + 8, 0xffffffffu);
    bus.Publish("CLUTTERSEG_OBJECTS", b.data(), b.size());
    clutterseg::status_t s{};
    s.camera_name = std::string(1, 'c');
    s.source = std::string(1, 's');
    b = Encode(s);
    PutBe32(&b, 8 + 8 + 6 + 6 + 5 + 8 + 5 + 4 + 32, 1u << 28);
    bus.Publish("CLUTTERSEG_STATUS", b.data(), b.size());
    // Two good frames, every array of the messages filled (the listener's checks follow
    // the types field by field: this fails when they fall out of step).
    for (int f = 0; f < 2; ++f) {
      clutterseg::objects_t good{};
      good.frame_seq = f;
      good.camera_name = std::string(1, 'c');
      good.num_planes = 1;
      good.planes.resize(1);
      good.num_objects = 2;
      good.objects.resize(2);
      good.frame_id = std::string("base_link");
      good.objects[1].num_samples = 3;
      good.objects[1].samples.assign(3, std::vector<float>(3, 0.5f));
      good.num_lost_tracks = 1;
      good.lost_tracks.resize(1);
      good.num_ended_tracks = 2;
      good.ended_track_ids = {4, 5};
      good.times.num_stages = 2;
      good.times.stage_names = {"points", "voxelize"};
      good.times.stage_ms = {1.f, 2.f};
      bus.PublishMessage("CLUTTERSEG_OBJECTS", good);
      clutterseg::label_image_t labels = RleImage(40, 20);
      labels.frame_seq = f;
      bus.PublishMessage("CLUTTERSEG_LABELS", labels);
    }
    s.frames_captured = 2;
    s.version = std::string("0.2.0");
    s.num_stages = 2;
    s.stage_names = {"points", "voxelize"};
    s.stage_p50_ms = {1.f, 2.f};
    s.stage_p99_ms = {1.f, 2.f};
    s.last_error = std::string("none");
    bus.PublishMessage("CLUTTERSEG_STATUS", s);
  }
  const fs::path png_dir = dir / "png";
  const testing::ProcessResult r = testing::RunProcess(
      {CLUTTERSEG_LISTEN_EXE, "--lcm-url", "file://" + log + "?speed=0", "--png", png_dir.string()},
      std::chrono::seconds(60));
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.exit_code, 5) << r.err;  // kExitIncomplete
  EXPECT_LT(r.max_rss_kib, 200 * 1024) << "KiB";
  EXPECT_NE(r.err.find("size = 2147483647 does not fit"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("16384x16384 px exceeds the frame limit"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("num_planes = 100000000 does not fit"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("camera_name has length -1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("num_stages = 268435456 does not fit"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("5 message(s) rejected"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(png_dir / "labels_000000.png"));
  EXPECT_TRUE(fs::exists(png_dir / "labels_000001.png"));
  EXPECT_NE(r.out.find("frame 1 utime"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("captured 2"), std::string::npos) << "good status_t printed: " << r.out;
}

// A negative --count is a bad command line (exit 2, naming the option), as for the daemon; it
// used to be taken as "run until ^C" and ended with 0 at the end of a log.
TEST(ListenBounds, NegativeCountIsAUsageError) {
  const testing::ProcessResult r = testing::RunProcess(
      {CLUTTERSEG_LISTEN_EXE, "--lcm-url", "file:///nonexistent.lcmlog?speed=0", "--count", "-1"},
      std::chrono::seconds(60));
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--count"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace clutterseg::daemon
