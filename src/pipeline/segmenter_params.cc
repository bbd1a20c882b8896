#include "clutterseg/pipeline/segmenter_params.h"

#include "clutterseg/core/param_check.h"

namespace clutterseg::pipeline {

void ObjectParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("min_object_points", min_object_points, 1, 100000000);
  check.InRange("support_min_area_m2", support_min_area_m2, 1e-6f, 1e4f, "m^2");
  check.InRange("support_snap_distance_m", support_snap_distance_m, 0.f, 1.f, "m");
  check.InRange("below_support_margin_m", below_support_margin_m, 0.f, 10.f, "m");
}

void SegmenterParams::ValidateOrThrow() const {
  points.ValidateOrThrow();
  supervoxel.ValidateOrThrow();
  linkage.ValidateOrThrow();
  planes.ValidateOrThrow();
  objects.ValidateOrThrow();
}

}  // namespace clutterseg::pipeline
