// ROS camera_info calibration files as camera_calibration writes them, and the ways they go
// wrong.
#include "clutterseg/config/camera_info.h"

#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "clutterseg/config/key_table.h"
#include "tests/testing/test_data.h"

namespace clutterseg::config {
namespace {

std::string Write(const std::string& name, const std::string& text) {
  const std::string path = (testing::ScratchDir("camera_info") / name).string();
  std::FILE* f = std::fopen(path.c_str(), "w");
  EXPECT_NE(f, nullptr);
  std::fputs(text.c_str(), f);
  std::fclose(f);
  return path;
}

std::string WithMatrix(const std::string& data, const std::string& size = "640, 480") {
  const size_t comma = size.find(',');
  return "image_width: " + size.substr(0, comma) + "\nimage_height:" + size.substr(comma + 1) +
         "\ncamera_name: depth_PS1080_PrimeSense\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
         "  data: [" +
         data +
         "]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n"
         "  data: [0.01, -0.02, 0, 0, 0]\nrectification_matrix:\n  rows: 3\n  cols: 3\n"
         "  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n";
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadCameraInfoYaml(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(CameraInfo, ReadsTheCameraMatrixAndImageSize) {
  const core::CameraIntrinsics k = ReadCameraInfoYaml(
      Write("xtion.yaml", WithMatrix("570.3422, 0, 314.5, 0, 570.3422, 235.5, 0, 0, 1")));
  EXPECT_EQ(k.width, 640);
  EXPECT_EQ(k.height, 480);
  EXPECT_DOUBLE_EQ(k.fx, 570.3422);
  EXPECT_DOUBLE_EQ(k.fy, 570.3422);
  EXPECT_DOUBLE_EQ(k.cx, 314.5);
  EXPECT_DOUBLE_EQ(k.cy, 235.5);
}

TEST(CameraInfo, ASecondDocumentAndTextThatHangsYamlCppsLoadAllAreRefused) {
  const std::string two =
      Write("two.yaml", WithMatrix("570, 0, 314.5, 0, 570, 235.5, 0, 0, 1") + "---\na: 1\n");
  EXPECT_NE(ErrorOf(two).find("line 17: a second YAML document"), std::string::npos)
      << ErrorOf(two);
  const std::string hang = Write("hang.yaml", ",\"kmg_height\":481,\"fx\":1e6fsoft\":248.1}\n");
  EXPECT_NE(ErrorOf(hang), "");
}

TEST(CameraInfo, MalformedFilesAreRefusedNamingTheField) {
  const std::string skew = Write("skew.yaml", WithMatrix("570, 3, 314.5, 0, 570, 235.5, 0, 0, 1"));
  EXPECT_NE(ErrorOf(skew).find("not [fx 0 cx; 0 fy cy; 0 0 1]"), std::string::npos)
      << ErrorOf(skew);
  const std::string short_data = Write("short.yaml", WithMatrix("570, 0, 314.5, 0, 570"));
  EXPECT_NE(ErrorOf(short_data).find("must hold 9 numbers"), std::string::npos);
  const std::string text = Write("text.yaml", WithMatrix("570, 0, abc, 0, 570, 235.5, 0, 0, 1"));
  EXPECT_NE(ErrorOf(text).find("'camera_matrix.data[2]' = 'abc' is not a number"),
            std::string::npos)
      << ErrorOf(text);
  const std::string no_size =
      Write("no_size.yaml", "camera_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}");
  EXPECT_NE(ErrorOf(no_size).find("'image_width' is missing"), std::string::npos)
      << ErrorOf(no_size);
  // A focal length of 30 px at 640 px is a field of view of 170 degrees: no camera.
  const std::string fisheye =
      Write("fisheye.yaml", WithMatrix("30, 0, 319.5, 0, 30, 239.5, 0, 0, 1"));
  EXPECT_NE(ErrorOf(fisheye).find("camera_matrix"), std::string::npos) << ErrorOf(fisheye);
  const std::string broken = Write("broken.yaml", "camera_matrix: [1, 2\n");
  EXPECT_NE(ErrorOf(broken).find("line"), std::string::npos) << ErrorOf(broken);
  EXPECT_NE(ErrorOf(broken).find(broken), std::string::npos) << "names the file";
}

}  // namespace
}  // namespace clutterseg::config
