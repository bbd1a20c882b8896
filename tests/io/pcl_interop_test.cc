// Checks the PCD reader and writer against PCL's own (built only with
// -DCLUTTERSEG_PCL_BASELINE=ON, which needs libpcl-dev).
#include <cmath>
#include <cstring>
#include <string>

#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include "clutterseg/io/pcd.h"
#include "tests/testing/test_data.h"

namespace clutterseg::io {
namespace {

bool SameFloat(float a, float b) {
  return (std::isnan(a) && std::isnan(b)) || std::memcmp(&a, &b, sizeof a) == 0;
}

size_t CountMismatches(const pcl::PointCloud<pcl::PointXYZRGBL>& pcl_cloud,
                       const core::PointCloud& cloud) {
  if (pcl_cloud.size() != cloud.size()) return cloud.size() + 1;
  size_t bad = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    const pcl::PointXYZRGBL& p = pcl_cloud.points[i];
    if (!SameFloat(p.x, cloud.xyz[i].x) || !SameFloat(p.y, cloud.xyz[i].y) ||
        !SameFloat(p.z, cloud.xyz[i].z) || p.rgba != cloud.rgba[i] || p.label != cloud.label[i]) {
      ++bad;
    }
  }
  return bad;
}

class PclInteropRealData : public ::testing::TestWithParam<PcdEncoding> {};

TEST_P(PclInteropRealData, BothDirections) {
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn6.pcd");
  const std::string source = (testing::DataDir() / "mosd-learn/learn6.pcd").string();
  const core::PointCloud ours = ReadPcd(source);
  pcl::PointCloud<pcl::PointXYZRGBL> reference;
  ASSERT_EQ(pcl::io::loadPCDFile(source, reference), 0);
  EXPECT_EQ(CountMismatches(reference, ours), 0u);

  const auto dir =
      testing::ScratchDir("pcl_interop_" + std::to_string(static_cast<int>(GetParam())));
  // PCL reads what we write.
  const std::string ours_path = (dir / "ours.pcd").string();
  WritePcd(ours_path, ours, GetParam());
  pcl::PointCloud<pcl::PointXYZRGBL> back;
  ASSERT_EQ(pcl::io::loadPCDFile(ours_path, back), 0);
  EXPECT_EQ(back.width, 640u);
  EXPECT_EQ(back.height, 480u);
  EXPECT_EQ(CountMismatches(back, ours), 0u);

  // We read what PCL writes.
  const std::string pcl_path = (dir / "pcl.pcd").string();
  pcl::PCDWriter writer;
  switch (GetParam()) {
    case PcdEncoding::kAscii:
      ASSERT_EQ(writer.writeASCII(pcl_path, reference, 9), 0);
      break;
    case PcdEncoding::kBinary:
      ASSERT_EQ(writer.writeBinary(pcl_path, reference), 0);
      break;
    case PcdEncoding::kBinaryCompressed:
      ASSERT_EQ(writer.writeBinaryCompressed(pcl_path, reference), 0);
      break;
  }
  const core::PointCloud from_pcl = ReadPcd(pcl_path);
  EXPECT_EQ(from_pcl.width, 640);
  EXPECT_EQ(from_pcl.height, 480);
  EXPECT_EQ(CountMismatches(reference, from_pcl), 0u);
}

INSTANTIATE_TEST_SUITE_P(AllEncodings, PclInteropRealData,
                         ::testing::Values(PcdEncoding::kAscii, PcdEncoding::kBinary,
                                           PcdEncoding::kBinaryCompressed));

TEST(PclPackedRgbTest, ReadsAllEncodings) {
  pcl::PointCloud<pcl::PointXYZRGB> cloud(4, 3);
  for (size_t i = 0; i < cloud.size(); ++i) {
    cloud.points[i].x = 0.1f * static_cast<float>(i);
    cloud.points[i].y = 1.f;
    cloud.points[i].z = 2.f;
    cloud.points[i].r = static_cast<uint8_t>(i * 20);
    cloud.points[i].g = 7;
    cloud.points[i].b = static_cast<uint8_t>(255 - i);
  }
  const auto dir = testing::ScratchDir("pcl_interop_rgb");
  pcl::PCDWriter writer;
  for (int encoding = 0; encoding < 3; ++encoding) {
    const std::string path = (dir / ("rgb" + std::to_string(encoding) + ".pcd")).string();
    if (encoding == 0) writer.writeASCII(path, cloud);
    if (encoding == 1) writer.writeBinary(path, cloud);
    if (encoding == 2) writer.writeBinaryCompressed(path, cloud);
    const core::PointCloud ours = ReadPcd(path);
    ASSERT_EQ(ours.size(), cloud.size());
    EXPECT_EQ(ours.width, 4);
    EXPECT_EQ(ours.height, 3);
    EXPECT_FALSE(ours.has_label());
    for (size_t i = 0; i < cloud.size(); ++i) {
      EXPECT_EQ(ours.xyz[i].x, cloud.points[i].x);
      const core::Rgb8 c = core::UnpackRgba(ours.rgba[i]);
      EXPECT_EQ(c.r, cloud.points[i].r);
      EXPECT_EQ(c.g, cloud.points[i].g);
      EXPECT_EQ(c.b, cloud.points[i].b);
      EXPECT_EQ(ours.rgba[i] >> 24, 0xffu);
    }
  }
}

}  // namespace
}  // namespace clutterseg::io
