#include "clutterseg/supervoxel/supervoxel_params.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace clutterseg::supervoxel {
namespace {

[[noreturn]] void Fail(const char* key, double value, const char* want) {
  std::ostringstream os;
  os << "supervoxel params: " << key << " = " << value << " is invalid (" << want << ")";
  throw std::invalid_argument(os.str());
}

bool Finite(float v) { return std::isfinite(v); }

}  // namespace

void SupervoxelParams::ValidateOrThrow() const {
  if (!(Finite(voxel_resolution_m) && voxel_resolution_m >= 1e-4f && voxel_resolution_m <= 1.f)) {
    Fail("voxel_resolution_m", voxel_resolution_m, "expected 0.0001..1 m");
  }
  if (!(Finite(seed_resolution_m) && seed_resolution_m >= voxel_resolution_m &&
        seed_resolution_m <= 100.f * voxel_resolution_m)) {
    Fail("seed_resolution_m", seed_resolution_m,
         "expected voxel_resolution_m..100 * voxel_resolution_m");
  }
  if (!(Finite(color_importance) && color_importance >= 0.f)) {
    Fail("color_importance", color_importance, "expected >= 0");
  }
  if (!(Finite(spatial_importance) && spatial_importance >= 0.f)) {
    Fail("spatial_importance", spatial_importance, "expected >= 0");
  }
  if (!(Finite(normal_importance) && normal_importance >= 0.f)) {
    Fail("normal_importance", normal_importance, "expected >= 0");
  }
  if (!(color_importance > 0.f || spatial_importance > 0.f || normal_importance > 0.f)) {
    Fail("spatial_importance", spatial_importance,
         "at least one of color/spatial/normal_importance must be > 0");
  }
  if (refinement_iterations < 0 || refinement_iterations > 100) {
    Fail("refinement_iterations", refinement_iterations, "expected 0..100");
  }
  if (growth_regions < 1 || growth_regions > 64) {
    Fail("growth_regions", growth_regions, "expected 1..64");
  }
  if (!(Finite(min_seed_occupancy) && min_seed_occupancy >= 0.f && min_seed_occupancy <= 1.f)) {
    Fail("min_seed_occupancy", min_seed_occupancy, "expected 0..1");
  }
  if (!(Finite(max_depth_m) && max_depth_m >= 0.f)) {
    Fail("max_depth_m", max_depth_m, "expected >= 0 m, 0 = no limit");
  }
}

}  // namespace clutterseg::supervoxel
