#include "clutterseg/config/camera_info.h"

#include <cmath>
#include <stdexcept>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "clutterseg/config/internal/yaml_file.h"
#include "clutterseg/config/key_table.h"

namespace clutterseg::config {
namespace {

constexpr const char* kKind = "camera_info";

[[noreturn]] void Fail(const std::string& path, const std::string& what) {
  internal::FailYamlFile(path, kKind, what);
}

double Number(const std::string& path, const YAML::Node& node, const std::string& field) {
  return internal::YamlNumber(path, kKind, node, field);
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
  const YAML::Node doc = internal::LoadYamlFile(path, kKind);
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
