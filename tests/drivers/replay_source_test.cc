#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/drivers/replay/depth_png_source.h"
#include "clutterseg/drivers/replay/pcd_directory_source.h"
#ifdef CLUTTERSEG_HAVE_SYNTHETIC_SOURCE
#include "clutterseg/drivers/replay/synthetic_source.h"
#endif
#include "clutterseg/io/pcd.h"
#include "clutterseg/io/png_io.h"
#include "tests/testing/test_data.h"

namespace clutterseg::drivers {
namespace {

using core::ReadStatus;

core::CameraIntrinsics OddIntrinsics() {
  core::CameraIntrinsics k;
  k.width = 160;
  k.height = 120;
  k.fx = 150.5;
  k.fy = 148.25;
  k.cx = 82.3;
  k.cy = 57.9;
  return k;
}

core::DepthImage RampDepth(int w, int h, int i) {
  core::DepthImage d(w, h);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      d.at(u, v) = ((u + v) % 11 == 0) ? 0 : static_cast<uint16_t>(600 + 3 * u + 2 * v + 10 * i);
    }
  }
  return d;
}

// Largest |difference| between two organized clouds over points finite in both; counts
// points finite in only one of them in `mismatched_validity`.
double MaxXyzError(const core::PointCloud& a, const core::PointCloud& b, int* mismatched_validity) {
  double worst = 0;
  *mismatched_validity = 0;
  for (size_t i = 0; i < a.xyz.size(); ++i) {
    const bool va = core::IsValid(a.xyz[i]) && a.xyz[i].z > 0.f;
    const bool vb = core::IsValid(b.xyz[i]);
    if (va != vb) {
      ++*mismatched_validity;
      continue;
    }
    if (!va) continue;
    worst = std::max({worst, std::abs(double{a.xyz[i].x} - b.xyz[i].x),
                      std::abs(double{a.xyz[i].y} - b.xyz[i].y),
                      std::abs(double{a.xyz[i].z} - b.xyz[i].z)});
  }
  return worst;
}

TEST(NaturalSortTest, NumbersCompareByValue) {
  std::vector<std::string> names{"learn10.pcd", "learn2.pcd",  "learn1.pcd",
                                 "a.pcd",       "learn02.pcd", "learn0.pcd"};
  internal::NaturalSort(&names);
  const std::vector<std::string> want{"a.pcd",      "learn0.pcd",  "learn1.pcd",
                                      "learn2.pcd", "learn02.pcd", "learn10.pcd"};
  EXPECT_EQ(names, want);
}

TEST(EstimateIntrinsicsTest, RecoversThePinholeOfAnOrganizedCloud) {
  const core::CameraIntrinsics k = OddIntrinsics();
  core::PointCloud cloud;
  core::DepthToPointCloud(RampDepth(160, 120, 0), k, nullptr, &cloud);
  double rms = -1;
  const core::CameraIntrinsics got = EstimateIntrinsics(cloud, &rms);
  EXPECT_EQ(got.width, 160);
  EXPECT_EQ(got.height, 120);
  EXPECT_NEAR(got.fx, k.fx, 1e-3);
  EXPECT_NEAR(got.fy, k.fy, 1e-3);
  EXPECT_NEAR(got.cx, k.cx, 1e-3);
  EXPECT_NEAR(got.cy, k.cy, 1e-3);
  EXPECT_LT(rms, 1e-3);

  core::PointCloud flat = cloud;
  flat.height = 1;
  flat.width = static_cast<int>(flat.xyz.size());
  EXPECT_THROW(EstimateIntrinsics(flat), std::runtime_error);
  core::PointCloud empty;
  empty.width = 4;
  empty.height = 4;
  empty.xyz.assign(16, core::Vec3f{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth});
  EXPECT_THROW(EstimateIntrinsics(empty), std::runtime_error);
}

TEST(CloudToDepthTest, ProjectsUnorganizedClouds) {
  const core::CameraIntrinsics k = OddIntrinsics();
  const core::DepthImage depth = RampDepth(160, 120, 1);
  core::PointCloud organized;
  core::DepthToPointCloud(depth, k, nullptr, &organized);
  core::PointCloud loose;
  loose.height = 1;
  for (const core::Vec3f& p : organized.xyz) {
    if (core::IsValid(p)) loose.xyz.push_back(p);
  }
  loose.width = static_cast<int>(loose.xyz.size());
  core::DepthImage got;
  core::ColorImage color;
  CloudToDepth(loose, k, &got, &color);
  ASSERT_EQ(got.width, 160);
  ASSERT_EQ(got.height, 120);
  EXPECT_TRUE(color.empty());
  int bad = 0;
  for (size_t i = 0; i < depth.data.size(); ++i) bad += got.data[i] != depth.data[i] ? 1 : 0;
  EXPECT_EQ(bad, 0);
}

TEST(PcdDirectorySourceTest, ReadsWrittenCloudsInOrderThenEndsOrLoops) {
  const auto dir = testing::ScratchDir("pcd_source_written");
  const core::CameraIntrinsics k = OddIntrinsics();
  for (int i = 0; i < 3; ++i) {
    core::PointCloud cloud;
    core::ColorImage color(160, 120, core::Rgb8{static_cast<uint8_t>(i), 20, 30});
    core::DepthToPointCloud(RampDepth(160, 120, i), k, &color, &cloud);
    io::WritePcd((dir / ("f" + std::to_string(i * 5) + ".pcd")).string(), cloud);
  }
  PcdDirectorySourceOptions o;
  o.path = dir.string();
  PcdDirectorySource src(o);
  src.Open();
  ASSERT_EQ(src.files().size(), 3u);
  EXPECT_NEAR(src.intrinsics().fx, k.fx, 0.01);
  EXPECT_NEAR(src.intrinsics().cy, k.cy, 0.01);
  core::RgbdFrame frame;
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(src.Read(100, &frame), ReadStatus::kOk) << src.last_error();
    EXPECT_EQ(frame.sequence, static_cast<uint64_t>(i));
    EXPECT_EQ(frame.utime, i * o.frame_period_us);
    const core::DepthImage want = RampDepth(160, 120, i);  // f0, f5, f10 in natural order
    int bad = 0;
    for (size_t p = 0; p < want.data.size(); ++p) bad += frame.depth.data[p] != want.data[p];
    EXPECT_EQ(bad, 0) << "frame " << i;
    ASSERT_EQ(frame.color.width, 160);
    EXPECT_EQ(frame.color.at(5, 5).r, i);
    EXPECT_EQ(frame.color.at(5, 5).g, 20);
  }
  EXPECT_EQ(src.Read(100, &frame), ReadStatus::kEndOfStream);

  o.loop = true;
  PcdDirectorySource looping(o);
  looping.Open();
  for (int n = 0; n < 7; ++n) ASSERT_EQ(looping.Read(100, &frame), ReadStatus::kOk);
  EXPECT_EQ(frame.sequence, 6u);
  EXPECT_EQ(frame.color.at(5, 5).r, 0);  // 7th read is the first file again

  PcdDirectorySourceOptions missing;
  missing.path = (dir / "nope").string();
  PcdDirectorySource none(missing);
  EXPECT_THROW(none.Open(), std::runtime_error);
}

TEST(PcdDirectorySourceRealData, ReproducesMosdXyzWithinDepthQuantisation) {
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn0.pcd");
  for (const bool estimate : {true, false}) {
    PcdDirectorySourceOptions o;
    o.path = (testing::DataDir() / "mosd-learn").string();
    o.estimate_intrinsics = estimate;  // mOSD's camera: fx = fy = 525, cx = 319.5, cy = 239.5
    PcdDirectorySource src(o);
    src.Open();
    EXPECT_EQ(src.files().size(), 45u);
    EXPECT_NE(src.files().front().find("learn0.pcd"), std::string::npos);
    EXPECT_NE(src.files()[2].find("learn2.pcd"), std::string::npos);
    if (estimate) {
      EXPECT_NEAR(src.intrinsics().fx, 525.0, 0.05);
      EXPECT_NEAR(src.intrinsics().fy, 525.0, 0.05);
      EXPECT_NEAR(src.intrinsics().cx, 319.5, 0.05);
      EXPECT_NEAR(src.intrinsics().cy, 239.5, 0.05);
    }
    core::RgbdFrame frame;
    core::PointCloud back;
    for (int i = 0; i < 2; ++i) {
      ASSERT_EQ(src.Read(100, &frame), ReadStatus::kOk) << src.last_error();
      const core::PointCloud original = io::ReadPcd(src.files()[static_cast<size_t>(i)]);
      ASSERT_EQ(frame.depth.width, 640);
      ASSERT_EQ(frame.depth.height, 480);
      ASSERT_EQ(frame.color.width, 640);
      core::DepthToPointCloud(frame.depth, frame.intrinsics, &frame.color, &back);
      int mismatched = 0;
      const double err = MaxXyzError(original, back, &mismatched);
      EXPECT_EQ(mismatched, 0);
      EXPECT_LE(err, 0.0010) << "frame " << i << " estimate " << estimate;
      EXPECT_GT(back.CountValid(), 10000u);
      size_t color_bad = 0;
      for (size_t p = 0; p < original.rgba.size(); ++p) {
        color_bad += (core::PackRgba(core::UnpackRgba(original.rgba[p])) & 0xFFFFFFu) !=
                     (back.rgba[p] & 0xFFFFFFu);
      }
      EXPECT_EQ(color_bad, 0u);
    }
  }
}

TEST(DepthPngSourceTest, FlatLayoutWithColourThenEndOrLoop) {
  const auto dir = testing::ScratchDir("png_source_flat");
  for (int i = 0; i < 3; ++i) {
    const std::string stem = (dir / ("00000" + std::to_string(i))).string();
    io::WriteDepthPng(stem + "-depth.png", RampDepth(64, 48, i));
    if (i != 1) {
      io::WriteColorPng(stem + "-color.png",
                        core::ColorImage(64, 48, core::Rgb8{static_cast<uint8_t>(i), 1, 2}));
    }
  }
  DepthPngSourceOptions o;
  o.directory = dir.string();
  o.intrinsics = core::DefaultKinectIntrinsics();
  DepthPngSource src(o);
  src.Open();
  ASSERT_EQ(src.entries().size(), 3u);
  EXPECT_TRUE(src.entries()[1].color.empty());
  core::RgbdFrame frame;
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(src.Read(100, &frame), ReadStatus::kOk) << src.last_error();
    const core::DepthImage want = RampDepth(64, 48, i);
    EXPECT_EQ(frame.depth.data, want.data) << i;
    EXPECT_EQ(frame.color.empty(), i == 1);
    if (i != 1) {
      EXPECT_EQ(frame.color.at(3, 3).r, i);
    }
    // 640x480 intrinsics are scaled to the 64x48 images.
    EXPECT_NEAR(frame.intrinsics.fx, 52.5, 1e-9);
    EXPECT_EQ(frame.intrinsics.width, 64);
  }
  EXPECT_EQ(src.Read(100, &frame), ReadStatus::kEndOfStream);
  EXPECT_EQ(src.Read(100, &frame), ReadStatus::kEndOfStream);

  o.loop = true;
  DepthPngSource looping(o);
  looping.Open();
  for (int n = 0; n < 4; ++n) ASSERT_EQ(looping.Read(100, &frame), ReadStatus::kOk);
  EXPECT_EQ(frame.depth.data, RampDepth(64, 48, 0).data);

  DepthPngSourceOptions empty;
  empty.directory = testing::ScratchDir("png_source_empty").string();
  DepthPngSource none(empty);
  EXPECT_THROW(none.Open(), std::runtime_error);
}

TEST(DepthPngSourceRealData, OsdPngMatchesMosdCloud) {
  CLUTTERSEG_REQUIRE_DATA("osd-png/depth/learn6.png");
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn6.pcd");
  DepthPngSourceOptions o;
  o.directory = (testing::DataDir() / "osd-png").string();  // split layout, no json: 525
  DepthPngSource src(o);
  src.Open();
  ASSERT_EQ(src.entries().size(), 1u);
  EXPECT_FALSE(src.entries()[0].color.empty());
  core::RgbdFrame frame;
  ASSERT_EQ(src.Read(100, &frame), ReadStatus::kOk) << src.last_error();
  ASSERT_EQ(frame.color.width, 640);
  const core::PointCloud mosd =
      io::ReadPcd((testing::DataDir() / "mosd-learn/learn6.pcd").string());
  ASSERT_EQ(mosd.xyz.size(), frame.depth.data.size());
  size_t common = 0;
  size_t bad = 0;
  for (size_t i = 0; i < mosd.xyz.size(); ++i) {
    if (!core::IsValid(mosd.xyz[i]) || frame.depth.data[i] == 0) continue;
    ++common;
    bad += std::lround(mosd.xyz[i].z * 1000.0) != frame.depth.data[i];
  }
  EXPECT_GT(common, 50000u);
  EXPECT_EQ(bad, 0u);
}

TEST(DepthPngSourceRealData, UcnDemoPairsColourAndReadsIntrinsicsJson) {
  CLUTTERSEG_REQUIRE_DATA("ucn-demo/camera_params.json");
  DepthPngSourceOptions o;
  o.directory = (testing::DataDir() / "ucn-demo").string();
  DepthPngSource src(o);
  src.Open();
  ASSERT_EQ(src.entries().size(), 9u);
  for (const auto& e : src.entries()) EXPECT_FALSE(e.color.empty()) << e.depth;
  EXPECT_NEAR(src.intrinsics().fx, 612.937, 1e-3);
  core::RgbdFrame frame;
  ASSERT_EQ(src.Read(100, &frame), ReadStatus::kOk) << src.last_error();
  EXPECT_EQ(frame.depth.width, 640);
  EXPECT_EQ(frame.color.width, 640);
  EXPECT_NE(src.Describe().find("9 depth frames"), std::string::npos) << src.Describe();
}

#ifdef CLUTTERSEG_HAVE_SYNTHETIC_SOURCE
SyntheticSourceOptions SmallSynthetic() {
  SyntheticSourceOptions o;
  o.seed = 7;
  o.num_frames = 4;
  o.intrinsics = core::DefaultKinectIntrinsics().Scaled(160, 120);
  return o;
}

size_t CountObjectPixels(const core::LabelImage& labels) {
  size_t n = 0;
  for (uint32_t l : labels.data) n += l != 0 ? 1 : 0;
  return n;
}

TEST(SyntheticSourceTest, IncrementalSequenceThenEndOfStream) {
  SyntheticSource src(SmallSynthetic());
  src.Open();
  core::RgbdFrame frame;
  std::vector<size_t> object_pixels;
  for (int k = 0; k < 4; ++k) {
    ASSERT_EQ(src.Read(1000, &frame), ReadStatus::kOk) << src.last_error();
    EXPECT_EQ(frame.sequence, static_cast<uint64_t>(k));
    EXPECT_EQ(frame.utime, k * int64_t{33333});
    ASSERT_EQ(frame.depth.width, 160);
    ASSERT_EQ(frame.color.width, 160);
    EXPECT_EQ(frame.intrinsics.width, 160);
    size_t valid = 0;
    for (uint16_t d : frame.depth.data) valid += d != 0 ? 1 : 0;
    EXPECT_GT(valid, frame.depth.data.size() / 2) << "frame " << k;
    object_pixels.push_back(CountObjectPixels(src.last_labels()));
  }
  EXPECT_EQ(object_pixels.front(), 0u);  // frame 0 is the empty table
  EXPECT_GT(object_pixels.back(), 0u);
  EXPECT_EQ(src.Read(1000, &frame), ReadStatus::kEndOfStream);
}

TEST(SyntheticSourceTest, DeterministicAndLoopsExactly) {
  SyntheticSourceOptions o = SmallSynthetic();
  o.num_frames = 2;
  o.loop = true;
  SyntheticSource a(o);
  o.render_threads = 2;
  SyntheticSource b(o);
  a.Open();
  b.Open();
  core::RgbdFrame fa;
  core::RgbdFrame fb;
  std::vector<std::vector<uint16_t>> depths;
  for (int k = 0; k < 3; ++k) {
    ASSERT_EQ(a.Read(1000, &fa), ReadStatus::kOk);
    ASSERT_EQ(b.Read(1000, &fb), ReadStatus::kOk);
    EXPECT_EQ(fa.depth.data, fb.depth.data) << k;
    depths.push_back(fa.depth.data);
  }
  EXPECT_EQ(depths[2], depths[0]);  // third read is frame 0 again
  EXPECT_EQ(fa.sequence, 2u);
}
#endif  // CLUTTERSEG_HAVE_SYNTHETIC_SOURCE

}  // namespace
}  // namespace clutterseg::drivers
