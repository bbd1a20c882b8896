#pragma once

namespace clutterseg::optimize {

/// Parameters of plane hypotheses and the alpha-expansion energy (docs/method.md 4-5).
struct PlaneParams {
  float inlier_distance_m{0.015f};     ///< rho: patch centroid to plane distance, metres
  float inlier_angle_deg{15.0f};       ///< normal compatibility of an inlier patch
  int min_inlier_patches{50};          ///< kappa (paper 50), in supervoxels
  float max_seed_curvature{0.01f};     ///< candidate patches must be flatter than this
  int max_planes{8};                   ///< stop after this many accepted planes
  float duplicate_angle_deg{5.0f};     ///< a candidate this close to an accepted plane ...
  float duplicate_distance_m{0.02f};   ///< ... and this near it is a duplicate
  float smoothness_weight{1.0f};       ///< lambda of the Potts term (per edge)
  float feature_weight{1.0f};          ///< scale of the feature term F
  float no_plane_cost_factor{2.0f};    ///< D(l0) = factor * rho
  int max_expansion_cycles{5};         ///< alpha-expansion sweeps over all labels

  /// @throws std::invalid_argument naming the key and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::optimize
