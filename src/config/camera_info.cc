#include "clutterseg/config/camera_info.h"

#include <cmath>
#include <stdexcept>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "clutterseg/config/key_table.h"

namespace clutterseg::config {
namespace {

[[noreturn]] void Fail(const std::string& path, const std::string& what) {
  throw ConfigError(path + ": camera_info: " + what);
}

double Number(const std::string& path, const YAML::Node& node, const std::string& field) {
  if (!node || !node.IsScalar()) Fail(path, "'" + field + "' is missing or not a number");
  try {
    const double v = node.as<double>();
    if (!std::isfinite(v)) Fail(path, "'" + field + "' = " + node.Scalar() + " is not finite");
    return v;
  } catch (const YAML::Exception&) {
    Fail(path, "'" + field + "' = '" + node.Scalar() + "' is not a number");
  }
}

int Dimension(const std::string& path, const YAML::Node& node, const std::string& field) {
  const double v = Number(path, node, field);
  if (v < 1 || v > 16384 || v != std::floor(v)) {
    Fail(path, "'" + field + "' = " + node.Scalar() + " is not an image size in pixels");
  }
  return static_cast<int>(v);
}

}  // namespace

core::CameraIntrinsics ReadCameraInfoYaml(const std::string& path) {
  const std::string text = internal::ReadConfigFile(path);
  YAML::Node doc;
  int second = 0;
  try {
    doc = YAML::Load(text);
    // yaml-cpp's Load() reads the first document and drops the rest without a word.
    second = internal::SecondYamlDocumentLine(text);
  } catch (const YAML::Exception& e) {
    Fail(path, "line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (second > 0) {
    Fail(path, "line " + std::to_string(second) +
                   ": a second YAML document; a camera_info file holds one");
  }
  if (!doc.IsMap()) Fail(path, "expected a mapping with image_width, image_height, camera_matrix");
  const YAML::Node matrix = doc["camera_matrix"];
  if (!matrix || !matrix.IsMap()) Fail(path, "'camera_matrix' is missing");
  if (Number(path, matrix["rows"], "camera_matrix.rows") != 3 ||
      Number(path, matrix["cols"], "camera_matrix.cols") != 3) {
    Fail(path, "camera_matrix is not 3x3");
  }
  const YAML::Node data = matrix["data"];
  if (!data || !data.IsSequence() || data.size() != 9) {
    Fail(path, "camera_matrix.data must hold 9 numbers");
  }
  std::vector<double> k(9);
  for (size_t i = 0; i < 9; ++i) {
    k[i] = Number(path, data[i], "camera_matrix.data[" + std::to_string(i) + "]");
  }
  if (k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0) {
    Fail(path, "camera_matrix is not [fx 0 cx; 0 fy cy; 0 0 1] (a skew or a scaled last row)");
  }
  core::CameraIntrinsics intr;
  intr.width = Dimension(path, doc["image_width"], "image_width");
  intr.height = Dimension(path, doc["image_height"], "image_height");
  intr.fx = k[0];
  intr.cx = k[2];
  intr.fy = k[4];
  intr.cy = k[5];
  try {
    intr.ValidateOrThrow("camera_matrix");
  } catch (const std::invalid_argument& e) {
    Fail(path, e.what());
  }
  return intr;
}

}  // namespace clutterseg::config
