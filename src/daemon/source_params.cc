#include "clutterseg/daemon/source_params.h"

#include <filesystem>
#include <stdexcept>

#include "clutterseg/config/extrinsics.h"
#include "clutterseg/core/param_check.h"
#include "clutterseg/io/extrinsics_json.h"
#include "clutterseg/pipeline/decimation.h"

namespace clutterseg::daemon {

void SourceParams::ValidateOrThrow() const {
  const core::ParamCheck check("camera");
  // The range of drivers::DepthPngSourceOptions::depth_scale_to_mm; the device keys are
  // checked by drivers::OpenNI2SourceOptions when the source is made.
  check.Require(depth_scale_mm > 0.0 && depth_scale_mm < 1000.0, "depth_scale_mm", depth_scale_mm,
                "(0, 1000) mm per PNG unit");
  check.InRange("decimation", decimation, 1, pipeline::kMaxDecimation, "(block edge, pixels)");
}

std::optional<core::Extrinsics> LoadExtrinsics(const SourceParams& camera) {
  if (camera.extrinsics_file.empty()) return std::nullopt;
  try {
    const std::filesystem::path ext = std::filesystem::path(camera.extrinsics_file).extension();
    return ext == ".yaml" || ext == ".yml" ? config::ReadExtrinsicsYaml(camera.extrinsics_file)
                                           : io::ReadExtrinsicsJson(camera.extrinsics_file);
  } catch (const std::exception& e) {
    throw std::invalid_argument("camera.extrinsics_file = '" + camera.extrinsics_file +
                                "': " + e.what());
  }
}

}  // namespace clutterseg::daemon
