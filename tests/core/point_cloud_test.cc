#include "clutterseg/core/point_cloud.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"

namespace clutterseg::core {
namespace {

TEST(DepthToPointCloud, BackProjectsWithPinholeModel) {
  CameraIntrinsics k;  // 640x480, f = 525, c = (319.5, 239.5)
  DepthImage depth(640, 480, 0);
  depth.at(0, 0) = 1000;
  depth.at(320, 240) = 2000;
  PointCloud cloud;
  DepthToPointCloud(depth, k, nullptr, &cloud);
  ASSERT_EQ(cloud.size(), 640u * 480u);
  EXPECT_TRUE(cloud.organized());
  EXPECT_EQ(cloud.CountValid(), 2u);
  const Vec3f p = cloud.xyz[0];
  EXPECT_NEAR(p.x, -319.5 / 525.0, 1e-6);
  EXPECT_NEAR(p.y, -239.5 / 525.0, 1e-6);
  EXPECT_NEAR(p.z, 1.0, 1e-6);
  const Vec3f q = cloud.xyz[240 * 640 + 320];
  EXPECT_NEAR(q.x, 0.5 * 2.0 / 525.0, 1e-6);
  EXPECT_FALSE(IsValid(cloud.xyz[1]));
  EXPECT_FALSE(cloud.has_color());
}

TEST(DepthToPointCloud, RangeLimitsInvalidate) {
  CameraIntrinsics k;
  DepthImage depth(640, 480, 500);
  depth.at(1, 0) = 5000;
  PointCloud cloud;
  DepthToPointCloud(depth, k, nullptr, &cloud, 0.6f, 4.0f);
  EXPECT_EQ(cloud.CountValid(), 0u);
}

TEST(DepthToPointCloud, DegenerateFocalLengthGivesNoValidPoint) {
  CameraIntrinsics k;
  k.fx = 0.0;  // unvalidated intrinsics of a broken recording: x = inf or NaN
  DepthImage depth(640, 480, 1000);
  PointCloud cloud;
  EXPECT_EQ(DepthToPointCloud(depth, k, nullptr, &cloud), 0u);
  EXPECT_EQ(cloud.CountValid(), 0u);
  k.fx = 525.0;
  EXPECT_EQ(DepthToPointCloud(depth, k, nullptr, &cloud), 640u * 480u);
}

TEST(DepthToPointCloud, PoolGivesTheSameCloud) {
  CameraIntrinsics k;
  DepthImage depth(640, 480, 0);
  ColorImage color(640, 480, Rgb8{});
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      // Holes, near and far depths and an edge every few pixels.
      depth.at(u, v) = static_cast<uint16_t>((u * 7 + v * 13) % 11 == 0 ? 0 : 400 + (u * v) % 5000);
      color.at(u, v) = Rgb8{static_cast<uint8_t>(u), static_cast<uint8_t>(v), 7};
    }
  }
  PointCloud serial, pooled;
  DepthToPointCloud(depth, k, &color, &serial, 0.5f, 4.0f);
  ThreadPool pool(3);
  DepthToPointCloud(depth, k, &color, &pooled, 0.5f, 4.0f, &pool);
  ASSERT_EQ(serial.size(), pooled.size());
  EXPECT_GT(serial.CountValid(), 100000u);
  EXPECT_LT(serial.CountValid(), serial.size());
  for (size_t i = 0; i < serial.size(); ++i) {
    const Vec3f a = serial.xyz[i], b = pooled.xyz[i];
    ASSERT_EQ(IsValid(a), IsValid(b)) << i;
    if (IsValid(a)) {
      ASSERT_EQ(a.x, b.x) << i;
      ASSERT_EQ(a.y, b.y) << i;
      ASSERT_EQ(a.z, b.z) << i;
    }
  }
  EXPECT_EQ(serial.rgba, pooled.rgba);
}

TEST(DepthToPointCloud, EveryPixelIsThePinholeFormulaBitForBit) {
  // Widths around the four-pixel steps of the vectorised loop (its tail is scalar), random
  // depths with holes and points outside the range: each point must be exactly
  // ((u - cx) / fx * z, (v - cy) / fy * z, z) in float as computed here, or invalid.
  std::mt19937 rng(5);
  for (int w : {1, 3, 4, 5, 7, 8, 9, 13, 640}) {
    const int h = 7;
    CameraIntrinsics k;
    k.width = w;
    k.height = h;
    k.cx = 0.37 * w;
    DepthImage depth(w, h, 0);
    for (uint16_t& d : depth.data) d = rng() % 4 == 0 ? 0 : static_cast<uint16_t>(rng() % 6000);
    PointCloud cloud;
    const size_t valid = DepthToPointCloud(depth, k, nullptr, &cloud, 0.5f, 4.0f);
    const float ifx = static_cast<float>(1.0 / k.fx), ify = static_cast<float>(1.0 / k.fy);
    size_t expected_valid = 0;
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const uint16_t d = depth.at(u, v);
        const float z = d * 0.001f;
        const Vec3f want{(static_cast<float>(u) - static_cast<float>(k.cx)) * ifx * z,
                         (static_cast<float>(v) - static_cast<float>(k.cy)) * ify * z, z};
        const bool ok = d != 0 && z >= 0.5f && z <= 4.0f;
        const Vec3f& got = cloud.xyz[static_cast<size_t>(v) * w + u];
        ASSERT_EQ(IsValid(got), ok) << w << " " << u << "," << v;
        if (!ok) continue;
        ++expected_valid;
        ASSERT_EQ(got.x, want.x) << w << " " << u << "," << v;
        ASSERT_EQ(got.y, want.y) << w << " " << u << "," << v;
        ASSERT_EQ(got.z, want.z) << w << " " << u << "," << v;
      }
    }
    EXPECT_EQ(valid, expected_valid) << w;
  }
}

TEST(CameraIntrinsics, ValidateNamesTheBadKey) {
  CameraIntrinsics k;
  k.fx = -1;
  try {
    k.ValidateOrThrow();
    FAIL() << "expected a throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fx"), std::string::npos);
  }
  EXPECT_NO_THROW(CameraIntrinsics{}.ValidateOrThrow());
}

TEST(CameraIntrinsics, ScalingKeepsPixelCentres) {
  CameraIntrinsics k;
  CameraIntrinsics half = k.Scaled(320, 240);
  EXPECT_DOUBLE_EQ(half.fx, 262.5);
  EXPECT_DOUBLE_EQ(half.cx, 159.5);
}

TEST(IntrinsicsForCloud, ScalesToAnOrganizedCloudOfAnotherSize) {
  PointCloud cloud;
  cloud.width = 320;
  cloud.height = 240;
  cloud.xyz.resize(320 * 240);
  const CameraIntrinsics k = IntrinsicsForCloud(DefaultKinectIntrinsics(), cloud);
  const CameraIntrinsics expected = DefaultKinectIntrinsics().Scaled(320, 240);
  EXPECT_EQ(k.width, 320);
  EXPECT_EQ(k.height, 240);
  EXPECT_DOUBLE_EQ(k.fx, expected.fx);
  EXPECT_DOUBLE_EQ(k.cx, expected.cx);
}

TEST(IntrinsicsForCloud, KeepsThemForAnUnorganizedCloudOrTheSameSize) {
  PointCloud unorganized;
  unorganized.width = 1000;
  unorganized.height = 1;
  unorganized.xyz.resize(1000);
  const CameraIntrinsics k{640, 480, 600.0, 610.0, 320.0, 250.0};
  EXPECT_DOUBLE_EQ(IntrinsicsForCloud(k, unorganized).fx, 600.0);
  EXPECT_EQ(IntrinsicsForCloud(k, unorganized).width, 640);
  PointCloud same;
  same.width = 640;
  same.height = 480;
  same.xyz.resize(640 * 480);
  EXPECT_DOUBLE_EQ(IntrinsicsForCloud(k, same).cy, 250.0);
}

}  // namespace
}  // namespace clutterseg::core
