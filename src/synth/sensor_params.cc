#include "clutterseg/synth/sensor_params.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "clutterseg/core/param_check.h"

namespace clutterseg::synth {
namespace {

// Every check goes through core::ParamCheck: one message format, naming the field.
[[noreturn]] void Invalid(const char* key, double value, const char* want) {
  const std::string_view w(want);
  core::ParamCheck("sensor").Fail(key, core::FormatParamValue(value),
                                  w.rfind("expected ", 0) == 0 ? w.substr(9) : w);
}

}  // namespace

void SensorParams::ValidateOrThrow() const {
  if (!(baseline_m > 0.0 && baseline_m < 1.0)) Invalid("baseline_m", baseline_m, "expected 0..1");
  if (!(disparity_focal_px > 0.0 && disparity_focal_px < 1e5)) {
    Invalid("disparity_focal_px", disparity_focal_px, "expected > 0");
  }
  if (!(disparity_step_px >= 0.0 && disparity_step_px <= 4.0)) {
    Invalid("disparity_step_px", disparity_step_px, "expected 0..4");
  }
  if (!(axial_sigma_base_m >= 0.0 && axial_sigma_base_m < 0.5)) {
    Invalid("axial_sigma_base_m", axial_sigma_base_m, "expected 0..0.5");
  }
  if (!(axial_sigma_quad_m >= 0.0 && axial_sigma_quad_m < 0.5)) {
    Invalid("axial_sigma_quad_m", axial_sigma_quad_m, "expected 0..0.5");
  }
  if (!std::isfinite(axial_sigma_offset_m))
    Invalid("axial_sigma_offset_m", axial_sigma_offset_m, "expected finite");
  if (!(axial_noise_correlation_px >= 0.0 && axial_noise_correlation_px <= 256.0)) {
    Invalid("axial_noise_correlation_px", axial_noise_correlation_px, "expected 0..256");
  }
  if (!(lateral_sigma_px >= 0.0 && lateral_sigma_px <= 3.0)) {
    Invalid("lateral_sigma_px", lateral_sigma_px, "expected 0..3");
  }
  if (!(max_incidence_deg > 0.0 && max_incidence_deg <= 90.0)) {
    Invalid("max_incidence_deg", max_incidence_deg, "expected 0..90");
  }
  if (!(min_range_m >= 0.0)) Invalid("min_range_m", min_range_m, "expected >= 0");
  if (!(max_range_m > min_range_m && max_range_m <= 65.0)) {
    Invalid("max_range_m", max_range_m, "expected min_range_m..65");
  }
  if (!(dropout_fraction >= 0.0 && dropout_fraction <= 1.0)) {
    Invalid("dropout_fraction", dropout_fraction, "expected 0..1");
  }
  if (!(edge_dropout_probability >= 0.0 && edge_dropout_probability <= 1.0)) {
    Invalid("edge_dropout_probability", edge_dropout_probability, "expected 0..1");
  }
  if (edge_cluster_px < 1 || edge_cluster_px > 64)
    Invalid("edge_cluster_px", edge_cluster_px, "expected 1..64");
  if (!(edge_jump_fraction > 0.0))
    Invalid("edge_jump_fraction", edge_jump_fraction, "expected > 0");
  if (!(color_noise_sigma >= 0.0 && color_noise_sigma <= 64.0)) {
    Invalid("color_noise_sigma", color_noise_sigma, "expected 0..64");
  }
}

SensorParams IdealSensorParams() {
  SensorParams p = NoiselessSensorParams();
  p.projector_shadows = false;
  p.max_incidence_deg = 90.0;
  return p;
}

SensorParams NoiselessSensorParams() {
  SensorParams p;
  p.disparity_step_px = 0.0;
  p.axial_noise = false;
  p.lateral_sigma_px = 0.0;
  p.dropout_fraction = 0.0;
  p.edge_dropout_probability = 0.0;
  p.color_noise_sigma = 0.0;
  return p;
}

}  // namespace clutterseg::synth
