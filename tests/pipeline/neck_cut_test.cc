// The neck cut on hand-made label images: two domes whose outlines touch are cut at the neck
// between them; one plane seen through a neck, an outline narrowed by an occluder in front,
// an unorganized cloud and an object without a neck are left as they are.
#include "clutterseg/pipeline/neck_cut.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"

namespace clutterseg::pipeline {
namespace {

constexpr int kW = 200;
constexpr int kH = 120;
constexpr float kZ = 1.f;  // the discs' rims, metres

// A frame of two discs of radius 40 px whose centres lie `gap` + 80 px apart along a row,
// both labelled 1 (one merged object). Each disc is a dome (a spherical cap rising 5 cm towards
// the camera) or, with `flat`, a part of the plane z = kZ. Pixels outside the discs are a
// background plane 10 cm behind.
struct Frame {
  core::PointCloud cloud;
  core::CameraIntrinsics intrinsics;
  SegmentationResult result;
};

Frame MakeFrame(double gap, bool flat) {
  Frame f;
  f.intrinsics.width = kW;
  f.intrinsics.height = kH;
  f.intrinsics.fx = f.intrinsics.fy = 525.0;
  f.intrinsics.cx = 0.5 * (kW - 1);
  f.intrinsics.cy = 0.5 * (kH - 1);
  f.cloud.width = kW;
  f.cloud.height = kH;
  f.cloud.xyz.resize(static_cast<size_t>(kW) * kH);
  f.result.width = kW;
  f.result.height = kH;
  f.result.labels.Reset(kW, kH, 0u);
  const double r = 40.0;
  const double cx[2] = {60.0, 60.0 + 2 * r + gap};
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      float z = kZ + 0.1f;
      for (const double c : cx) {
        const double d = std::hypot(u - c, v - 60.0) / r;
        if (d <= 1.0) {
          z = flat ? kZ : kZ - 0.05f * static_cast<float>(std::sqrt(1.0 - d * d));
          f.result.labels.at(u, v) = 1;
        }
      }
      f.cloud.xyz[static_cast<size_t>(v) * kW + u] =
          core::Vec3f{static_cast<float>((u - f.intrinsics.cx) / f.intrinsics.fx) * z,
                      static_cast<float>((v - f.intrinsics.cy) / f.intrinsics.fy) * z, z};
    }
  }
  f.result.objects.assign(1, Object{});
  return f;
}

// Pixels labelled `label` left and right of the image's middle.
std::pair<int, int> CountSides(const SegmentationResult& r, uint32_t label) {
  int left = 0, right = 0;
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      if (r.labels.at(u, v) != label) continue;
      (u < 100 ? left : right) += 1;
    }
  }
  return {left, right};
}

TEST(NeckCut, TwoDomesTouchingAtAPointAreCutIntoTwoObjects) {
  // The discs touch at one pixel: their outline's neck is a few pixels wide.
  Frame f = MakeFrame(0.0, false);
  ObjectParams params;
  core::ThreadPool pool(2);
  NeckCutter cutter(params);
  NeckCutter pooled(params, &pool);
  Frame g = f;
  EXPECT_EQ(cutter.Compute(f.cloud, f.intrinsics, &f.result), 1u);
  EXPECT_EQ(pooled.Compute(g.cloud, g.intrinsics, &g.result), 1u);
  EXPECT_EQ(f.result.labels.data, g.result.labels.data);
  ASSERT_EQ(f.result.objects.size(), 2u);
  // Object 1 (first pixel, the left disc's top) is the left dome, object 2 the right one.
  const auto [l1, r1] = CountSides(f.result, 1);
  const auto [l2, r2] = CountSides(f.result, 2);
  EXPECT_GT(l1, 4900);
  EXPECT_LT(r1, 40);
  EXPECT_GT(r2, 4900);
  EXPECT_LT(l2, 40);
}

TEST(NeckCut, AWideJoinIsNoNeck) {
  // Overlapping by 30 pixels, the join is about 68 px (13 cm at 1 m) wide.
  Frame f = MakeFrame(-30.0, false);
  const std::vector<uint32_t> before = f.result.labels.data;
  NeckCutter cutter{ObjectParams{}};
  EXPECT_EQ(cutter.Compute(f.cloud, f.intrinsics, &f.result), 0u);
  EXPECT_EQ(f.result.labels.data, before);
  EXPECT_EQ(f.result.objects.size(), 1u);
}

TEST(NeckCut, OnePlaneSeenThroughANeckStaysWhole) {
  Frame f = MakeFrame(0.0, true);
  const std::vector<uint32_t> before = f.result.labels.data;
  NeckCutter cutter{ObjectParams{}};
  EXPECT_EQ(cutter.Compute(f.cloud, f.intrinsics, &f.result), 0u);
  EXPECT_EQ(f.result.labels.data, before);
}

TEST(NeckCut, AnOutlineNarrowedByAnOccluderInFrontStaysWhole) {
  // Something 20 cm in front of the domes covers the background beside the neck (above and
  // below it in the image); it is not the object's.
  Frame f = MakeFrame(0.0, false);
  for (int v = 0; v < kH; ++v) {
    for (int u = 90; u < 110; ++u) {
      if (f.result.labels.at(u, v) != 0) continue;
      core::Vec3f& p = f.cloud.xyz[static_cast<size_t>(v) * kW + u];
      const float z = kZ - 0.2f;
      p = core::Vec3f{p.x / p.z * z, p.y / p.z * z, z};
    }
  }
  const std::vector<uint32_t> before = f.result.labels.data;
  NeckCutter cutter{ObjectParams{}};
  EXPECT_EQ(cutter.Compute(f.cloud, f.intrinsics, &f.result), 0u);
  EXPECT_EQ(f.result.labels.data, before);
  // Without the occlusion test it is cut.
  ObjectParams no_test;
  no_test.neck_cut_max_occluded_share = 1.f;
  NeckCutter cutter_no_test(no_test);
  EXPECT_EQ(cutter_no_test.Compute(f.cloud, f.intrinsics, &f.result), 1u);
}

TEST(NeckCut, InvalidPointsInTheObjectAreSkipped) {
  // Every seventh pixel of the domes has no depth (labelled all the same): the cut is made as
  // without them.
  Frame f = MakeFrame(0.0, false);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = 0; i < f.cloud.xyz.size(); i += 7) {
    if (f.result.labels.data[i] != 0) f.cloud.xyz[i] = core::Vec3f{nan, nan, nan};
  }
  NeckCutter cutter{ObjectParams{}};
  EXPECT_EQ(cutter.Compute(f.cloud, f.intrinsics, &f.result), 1u);
  EXPECT_EQ(f.result.objects.size(), 2u);
}

TEST(NeckCut, OffOrUnorganizedLeavesTheLabels) {
  Frame f = MakeFrame(0.0, false);
  const std::vector<uint32_t> before = f.result.labels.data;
  ObjectParams off;
  off.neck_cut_max_width_m = 0.f;
  NeckCutter cutter_off(off);
  EXPECT_EQ(cutter_off.Compute(f.cloud, f.intrinsics, &f.result), 0u);
  EXPECT_EQ(f.result.labels.data, before);
  // The same points as one row: no image outline.
  f.cloud.width = kW * kH;
  f.cloud.height = 1;
  NeckCutter cutter{ObjectParams{}};
  EXPECT_EQ(cutter.Compute(f.cloud, f.intrinsics, &f.result), 0u);
  EXPECT_EQ(f.result.labels.data, before);
}

TEST(NeckCut, InvalidParametersNameTheKey) {
  ObjectParams bad;
  bad.neck_cut_max_occluded_share = 1.5f;
  EXPECT_THROW(NeckCutter{bad}, std::invalid_argument);
  bad = ObjectParams{};
  bad.neck_cut_max_width_m = -0.01f;
  try {
    NeckCutter cutter(bad);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("neck_cut_max_width_m = -0.01"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace clutterseg::pipeline
