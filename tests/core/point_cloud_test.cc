#include "core/point_cloud.h"

#include <cmath>
#include <stdexcept>

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace clutterseg::core
