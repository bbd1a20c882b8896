#include "clutterseg/daemon/regress.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "clutterseg/daemon/lcm_bus.h"
#include "clutterseg/daemon/messages.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "tests/daemon/daemon_test_util.h"
#include "tests/testing/test_data.h"

namespace clutterseg::daemon {
namespace {

// A run of `frames` frames with two box objects; `shift_m` moves object 2 along x and
// `drop_frame` leaves one frame out.
std::string WriteRun(const std::string& name, int frames, float shift_m, int drop_frame = -1,
                     int mask_shift_px = 0) {
  const std::string path = (testing::ScratchDir("regress_" + name) / "run.lcmlog").string();
  LcmBus bus("file://" + path + "?mode=w");
  for (int f = 0; f < frames; ++f) {
    if (f == drop_frame) continue;
    clutterseg::objects_t m{};
    m.frame_seq = f;
    m.num_objects = 2;
    m.objects.resize(2);
    m.objects[0].id = 1;
    m.objects[0].centroid[0] = -0.2f;
    m.objects[0].centroid[2] = 1.0f;
    m.objects[1].id = 2;
    m.objects[1].centroid[0] = 0.2f + shift_m;
    m.objects[1].centroid[2] = 1.0f;
    bus.PublishMessage("CLUTTERSEG_OBJECTS", m);
    core::LabelImage labels(40, 20, 0);
    for (int v = 5; v < 15; ++v) {
      for (int u = 2; u < 12; ++u) labels.at(u, v) = 1;
      for (int u = 22 + mask_shift_px; u < 32 + mask_shift_px; ++u) labels.at(u, v) = 2;
    }
    FrameInfo info;
    info.frame_seq = f;
    clutterseg::label_image_t l;
    EncodeLabelImage(labels, info, LabelCompression::kRle, &l);
    bus.PublishMessage("CLUTTERSEG_LABELS", l);
  }
  return path;
}

TEST(Regress, IdenticalRunsPass) {
  const std::string a = WriteRun("same_a", 4, 0.f);
  const std::string b = WriteRun("same_b", 4, 0.f);
  const RegressReport r = CompareLogs(a, b, RegressOptions{});
  EXPECT_TRUE(r.ok) << r.ToString(RegressOptions{});
  ASSERT_EQ(r.frames.size(), 4u);
  EXPECT_EQ(r.frames[0].matched, 2);
  EXPECT_DOUBLE_EQ(r.frames[0].mean_iou, 1.0);
}

TEST(Regress, CentroidShiftBeyondToleranceFails) {
  const std::string a = WriteRun("shift_a", 3, 0.f);
  const std::string b = WriteRun("shift_b", 3, 0.02f);
  RegressOptions o;
  const RegressReport r = CompareLogs(a, b, o);
  EXPECT_FALSE(r.ok);
  EXPECT_NEAR(r.frames[0].max_centroid_error_m, 0.02, 1e-6);
  EXPECT_NE(r.ToString(o).find("centroid error"), std::string::npos);
  o.centroid_tol_m = 0.03;
  EXPECT_TRUE(CompareLogs(a, b, o).ok);
}

TEST(Regress, MaskIouAndMissingFramesAreChecked) {
  const std::string a = WriteRun("iou_a", 3, 0.f);
  const std::string b = WriteRun("iou_b", 3, 0.f, -1, 5);  // object 2's mask moved 5 px
  RegressOptions o;
  const RegressReport r = CompareLogs(a, b, o);
  EXPECT_FALSE(r.ok);
  // Object 2: 50 of 150 pixels overlap -> IoU 1/3; object 1 -> 1; mean 2/3.
  EXPECT_NEAR(r.frames[0].mean_iou, (1.0 + 1.0 / 3.0) / 2.0, 1e-9);
  o.min_iou = 0.6;
  EXPECT_TRUE(CompareLogs(a, b, o).ok);

  const std::string c = WriteRun("missing_c", 3, 0.f, 1);
  const RegressReport rm = CompareLogs(a, c, RegressOptions{});
  EXPECT_FALSE(rm.ok);
  EXPECT_EQ(rm.only_in_a, (std::vector<int64_t>{1}));
}

TEST(Regress, ToolExitCodes) {
  const std::string a = WriteRun("tool_a", 2, 0.f);
  const std::string b = WriteRun("tool_b", 2, 0.05f);
  std::string err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_REGRESS_EXE, a, a}, std::chrono::seconds(60), &err), 0)
      << err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_REGRESS_EXE, a, b}, std::chrono::seconds(60), &err), 1)
      << err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_REGRESS_EXE, a, b, "--centroid-tol-m", "0.1"},
                          std::chrono::seconds(60), &err),
            0)
      << err;
  err.clear();
  EXPECT_EQ(testutil::Run({CLUTTERSEG_REGRESS_EXE, a, "/nonexistent/x.lcmlog"},
                          std::chrono::seconds(60), &err),
            2);
  EXPECT_NE(err.find("/nonexistent/x.lcmlog"), std::string::npos) << err;
}

// liblcm's reader stops silently at a damaged event, so a torn or damaged log was compared in
// part ("0 frames compared"); and it allocates what a damaged header claims (found by the
// lcm_log fuzz target: a 514-byte log took 13 s under ASan). Such logs are refused, naming the
// byte; the tool exits 2.
TEST(Regress, ATornOrDamagedLogIsRefusedNamingTheByte) {
  const std::string a = WriteRun("torn_a", 3, 0.f);
  const std::string torn = WriteRun("torn_b", 3, 0.f);
  std::filesystem::resize_file(torn, std::filesystem::file_size(torn) - 5);
  EXPECT_THROW(
      {
        try {
          CompareLogs(a, torn, RegressOptions{});
        } catch (const std::runtime_error& e) {
          EXPECT_NE(std::string(e.what()).find(torn + ": not a whole LCM log: truncated event at "
                                                      "byte "),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      std::runtime_error);
  const std::string damaged = WriteRun("damaged_b", 3, 0.f);
  {
    // The sync word of the second event, overwritten.
    std::fstream f(damaged, std::ios::in | std::ios::out | std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    const size_t second = bytes.find("\xED\xA1\xDA\x01", 4);
    ASSERT_NE(second, std::string::npos);
    f.seekp(static_cast<std::streamoff>(second));
    f.write("\x7f\x7f\x7f\x7f", 4);
  }
  std::string err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_REGRESS_EXE, a, damaged}, std::chrono::seconds(60), &err), 2);
  EXPECT_NE(err.find(damaged + ": not a whole LCM log"), std::string::npos) << err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_REGRESS_EXE, a, a}, std::chrono::seconds(60), &err), 0)
      << err;
}

// A FIFO given as a log used to block the scan's open until a writer came (clutterseg-regress
// hung): refused at once, exit 2, naming it.
TEST(Regress, AFifoIsRefusedWithoutBlocking) {
  const std::string a = WriteRun("fifo_a", 3, 0.f);
  const std::string fifo = (std::filesystem::path(a).parent_path() / "log.fifo").string();
  std::filesystem::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  std::string err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_REGRESS_EXE, a, fifo}, std::chrono::seconds(60), &err), 2);
  EXPECT_NE(err.find(fifo + ": not a whole LCM log: not a regular file"), std::string::npos) << err;
}

TEST(Listen, PrintsObjectsAndWritesLabelPngsFromALog) {
  const std::string a = WriteRun("listen_a", 3, 0.f);
  const auto png_dir = testing::ScratchDir("listen_png");
  std::string err;
  EXPECT_EQ(testutil::Run({CLUTTERSEG_LISTEN_EXE, "--lcm-url", "file://" + a + "?speed=0", "--png",
                           png_dir.string(), "--count", "3"},
                          std::chrono::seconds(60), &err),
            0)
      << err;
  for (int f = 0; f < 3; ++f) {
    char name[32];
    std::snprintf(name, sizeof(name), "labels_%06d.png", f);
    EXPECT_TRUE(std::filesystem::exists(png_dir / name)) << name;
  }
}

}  // namespace
}  // namespace clutterseg::daemon
