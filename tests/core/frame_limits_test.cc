#include "clutterseg/core/frame_limits.h"

#include <atomic>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "clutterseg/core/source_report.h"

namespace clutterseg::core {
namespace {

TEST(FrameLimits, DefaultsAcceptRealSensorsAndRefuseLargerDeclarations) {
  const FrameLimits dut_;
  EXPECT_NO_THROW(dut_.ValidateOrThrow());
  for (auto [w, h] : {std::pair{640, 480}, {1280, 720}, {1024, 1024}, {3840, 2160}, {4096, 4096}}) {
    EXPECT_FALSE(dut_.CheckImage(w, h, 20)) << w << "x" << h;  // a cloud: xyz rgba label
  }
  EXPECT_TRUE(dut_.CheckImage(4097, 10, 2));
  EXPECT_TRUE(dut_.CheckImage(10, 4097, 2));
  const std::optional<std::string> huge = dut_.CheckImage(16384, 16384, 2);
  ASSERT_TRUE(huge);
  EXPECT_EQ(*huge, "16384x16384 px exceeds the frame limit of 4096x4096 px");
  EXPECT_TRUE(dut_.CheckImage(0, 480, 2));
  EXPECT_TRUE(dut_.CheckImage(-640, 480, 2));
  EXPECT_TRUE(dut_.CheckImage(std::numeric_limits<int64_t>::max(), 2, 2));
  // 4096 x 4096 at 33 bytes per point is beyond the 512 MiB of one buffer.
  const std::optional<std::string> bytes = dut_.CheckImage(4096, 4096, 33);
  ASSERT_TRUE(bytes);
  EXPECT_NE(bytes->find("512 MiB"), std::string::npos) << *bytes;

  EXPECT_FALSE(dut_.CheckPoints(0, 20));
  EXPECT_FALSE(dut_.CheckPoints(uint64_t{4096} * 4096, 20));
  EXPECT_TRUE(dut_.CheckPoints(uint64_t{4096} * 4096 + 1, 20));
  EXPECT_TRUE(dut_.CheckPoints(std::numeric_limits<uint64_t>::max(), 1 << 20));  // no overflow
  EXPECT_FALSE(dut_.CheckBytes(uint64_t{512} << 20));
  EXPECT_TRUE(dut_.CheckBytes((uint64_t{512} << 20) + 1));
}

TEST(FrameLimits, ValidateNamesTheField) {
  FrameLimits dut_;
  dut_.max_width = 0;
  try {
    dut_.ValidateOrThrow("camera.limits");
    ADD_FAILURE() << "accepted max_width 0";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("camera.limits.max_width = 0"), std::string::npos)
        << e.what();
  }
  dut_ = FrameLimits{};
  dut_.max_bytes = 10;
  EXPECT_THROW(dut_.ValidateOrThrow(), std::invalid_argument);
}

TEST(SourceCounters, CountsReasonsAndKeepsTheRecentSkipsNumbered) {
  SourceCounters dut_;
  EXPECT_EQ(dut_.Snapshot().frames_in_source, -1);
  dut_.SetFramesInSource(40);
  for (int i = 0; i < 35; ++i) dut_.Delivered(i % 7 == 0, i % 5 == 0);
  dut_.Skipped(SkipReason::kUnreadable, "a.pcd: truncated");
  dut_.Skipped(SkipReason::kTooLarge, "b.png: huge");
  dut_.Skipped(SkipReason::kNotDelivered, "rec.oni: 3 missing", 3);
  dut_.ColorUnmatched(2);
  dut_.PassCompleted();
  const SourceReport r = dut_.Snapshot();
  EXPECT_EQ(r.frames_delivered, 35u);
  EXPECT_EQ(r.frames_empty, 5u);
  EXPECT_EQ(r.frames_without_color, 7u);
  EXPECT_EQ(r.frames_skipped(), 5u);
  EXPECT_EQ(r.skipped_for(SkipReason::kNotDelivered), 3u);
  EXPECT_EQ(r.frames_delivered + r.frames_skipped(), 40u);
  EXPECT_TRUE(r.lost_frames());
  EXPECT_FALSE(r.all_empty());
  ASSERT_EQ(r.recent_skips.size(), 3u);
  EXPECT_EQ(r.recent_skips[0].serial, 1u);
  EXPECT_EQ(r.recent_skips[2].serial, 5u);
  EXPECT_EQ(r.recent_skips[2].count, 3u);
  const std::string line = r.ToString();
  EXPECT_NE(line.find("35 of 40 frames delivered, 5 skipped (1 unreadable, 1 too_large, 3 "
                      "not_delivered)"),
            std::string::npos)
      << line;
  EXPECT_NE(line.find("last skipped: rec.oni: 3 missing"), std::string::npos) << line;

  // Only the most recent entries are kept.
  for (int i = 0; i < 100; ++i) dut_.Skipped(SkipReason::kUnreadable, "x");
  const SourceReport many = dut_.Snapshot();
  EXPECT_EQ(many.recent_skips.size(), SourceReport::kMaxRecentSkips);
  EXPECT_EQ(many.recent_skips.back().serial, 105u);
  EXPECT_EQ(many.frames_skipped(), 105u);
}

TEST(SourceCounters, AllEmptyNeedsAFrame) {
  SourceCounters dut_;
  EXPECT_FALSE(dut_.Snapshot().all_empty());
  dut_.Delivered(true);
  dut_.Delivered(true);
  EXPECT_TRUE(dut_.Snapshot().all_empty());
  dut_.Delivered(false);
  EXPECT_FALSE(dut_.Snapshot().all_empty());
}

// One thread counts while another takes snapshots: every snapshot is consistent (under
// ThreadSanitizer, this also checks that nothing races).
TEST(SourceCounters, SnapshotsWhileCounting) {
  SourceCounters dut_;
  std::atomic<bool> done{false};
  std::thread counter([&] {
    for (int i = 0; i < 20000; ++i) {
      dut_.Delivered(false);
      if (i % 100 == 0) dut_.Skipped(SkipReason::kUnreadable, "f");
    }
    done.store(true);
  });
  uint64_t last = 0;
  while (!done.load()) {
    const SourceReport r = dut_.Snapshot();
    EXPECT_GE(r.frames_delivered, last);
    last = r.frames_delivered;
    EXPECT_LE(r.recent_skips.size(), SourceReport::kMaxRecentSkips);
  }
  counter.join();
  EXPECT_EQ(dut_.Snapshot().frames_delivered, 20000u);
  EXPECT_EQ(dut_.Snapshot().frames_skipped(), 200u);
}

}  // namespace
}  // namespace clutterseg::core
