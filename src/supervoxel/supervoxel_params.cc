#include "clutterseg/supervoxel/supervoxel_params.h"

#include "clutterseg/core/param_check.h"

namespace clutterseg::supervoxel {

void SupervoxelParams::ValidateOrThrow() const {
  grid.ValidateOrThrow(kSection);
  const core::ParamCheck check(kSection);
  const float voxel = grid.voxel_resolution_m;
  check.InRange("seed_resolution_m", seed_resolution_m, voxel, 100.f * voxel,
                "m (voxel_resolution_m .. 100 * voxel_resolution_m)");
  check.AtLeast("color_importance", color_importance, 0.f);
  check.AtLeast("spatial_importance", spatial_importance, 0.f);
  check.AtLeast("normal_importance", normal_importance, 0.f);
  check.Require(color_importance > 0.f || spatial_importance > 0.f || normal_importance > 0.f,
                "spatial_importance", spatial_importance,
                "> 0 when color_importance and normal_importance are 0");
  check.InRange("refinement_iterations", refinement_iterations, 0, 100);
  check.InRange("max_supervoxels", max_supervoxels, 1, 1 << 24);
  check.InRange("growth_regions", growth_regions, 1, 64);
  check.InRange("min_seed_occupancy", min_seed_occupancy, 0.f, 1.f);
}

}  // namespace clutterseg::supervoxel
