#include "clutterseg/optimize/plane_params.h"

#include "clutterseg/core/param_check.h"

namespace clutterseg::optimize {

void PlaneParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("inlier_distance_m", inlier_distance_m, 1e-4f, 1.f, "m");
  check.InRange("inlier_angle_deg", inlier_angle_deg, 0.01f, 90.f, "deg");
  check.InRange("min_inlier_patches", min_inlier_patches, 1, 1000000);
  check.InRange("max_seed_curvature", max_seed_curvature, 0.f, 1.f);
  check.InRange("max_planes", max_planes, 0, 64);
  check.InRange("duplicate_angle_deg", duplicate_angle_deg, 0.01f, 90.f, "deg");
  check.InRange("duplicate_distance_m", duplicate_distance_m, 0.f, 10.f, "m");
  check.InRange("fixed_fit_max_angle_deg", fixed_fit_max_angle_deg, 0.f, 90.f, "deg");
  check.InRange("smoothness_weight", smoothness_weight, 0.f, 1e6f);
  check.InRange("feature_weight", feature_weight, 0.f, 1e6f);
  check.InRange("no_plane_cost_factor", no_plane_cost_factor, 0.f, 1e6f);
  check.InRange("max_expansion_cycles", max_expansion_cycles, 0, 100);
  check.InRange("normal_mismatch_cost", normal_mismatch_cost, 0.f, 1e6f);
  check.InRange("max_candidate_trials", max_candidate_trials, 0, 100000);
  check.InRange("seed_neighborhood_m", seed_neighborhood_m, 0.f, 10.f, "m");
  check.InRange("min_patch_points", min_patch_points, 3, 1000000);
  check.InRange("refit_iterations", refit_iterations, 0, 100);
}

}  // namespace clutterseg::optimize
