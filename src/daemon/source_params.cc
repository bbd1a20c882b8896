#include "clutterseg/daemon/source_params.h"

#include "clutterseg/core/param_check.h"

namespace clutterseg::daemon {

void SourceParams::ValidateOrThrow() const {
  const core::ParamCheck check("camera");
  // The range of drivers::DepthPngSourceOptions::depth_scale_to_mm; the device keys are
  // checked by drivers::OpenNI2SourceOptions when the source is made.
  check.Require(depth_scale_mm > 0.0 && depth_scale_mm < 1000.0, "depth_scale_mm", depth_scale_mm,
                "(0, 1000) mm per PNG unit");
}

}  // namespace clutterseg::daemon
