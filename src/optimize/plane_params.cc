#include "clutterseg/optimize/plane_params.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace clutterseg::optimize {
namespace {

[[noreturn]] void Fail(const char* key, const std::string& value, const char* why) {
  throw std::invalid_argument(std::string("planes.") + key + " = " + value + ": " + why);
}

void CheckPositive(const char* key, float v) {
  if (!std::isfinite(v) || v <= 0.f) Fail(key, std::to_string(v), "must be > 0");
}

void CheckNonNegative(const char* key, float v) {
  if (!std::isfinite(v) || v < 0.f) Fail(key, std::to_string(v), "must be >= 0");
}

void CheckAngle(const char* key, float v) {
  if (!std::isfinite(v) || v <= 0.f || v > 90.f) Fail(key, std::to_string(v), "must be in (0, 90]");
}

void CheckAtLeast(const char* key, int v, int min) {
  if (v < min) Fail(key, std::to_string(v), ("must be >= " + std::to_string(min)).c_str());
}

}  // namespace

void PlaneParams::ValidateOrThrow() const {
  CheckPositive("inlier_distance_m", inlier_distance_m);
  CheckAngle("inlier_angle_deg", inlier_angle_deg);
  CheckAtLeast("min_inlier_patches", min_inlier_patches, 1);
  CheckNonNegative("max_seed_curvature", max_seed_curvature);
  CheckAtLeast("max_planes", max_planes, 0);
  CheckAngle("duplicate_angle_deg", duplicate_angle_deg);
  CheckNonNegative("duplicate_distance_m", duplicate_distance_m);
  CheckNonNegative("smoothness_weight", smoothness_weight);
  CheckNonNegative("feature_weight", feature_weight);
  CheckNonNegative("no_plane_cost_factor", no_plane_cost_factor);
  CheckAtLeast("max_expansion_cycles", max_expansion_cycles, 0);
  CheckNonNegative("normal_mismatch_cost", normal_mismatch_cost);
  CheckAtLeast("max_candidate_trials", max_candidate_trials, 0);
  CheckNonNegative("seed_neighborhood_m", seed_neighborhood_m);
  CheckAtLeast("min_patch_points", min_patch_points, 3);
  CheckAtLeast("refit_iterations", refit_iterations, 0);
}

}  // namespace clutterseg::optimize
