#pragma once

#include <string_view>

namespace clutterseg::optimize {

/// Parameters of plane hypotheses and the alpha-expansion energy (docs/method.md 4-5).
///
/// Energy units: every term is expressed in units of rho (`inlier_distance_m`), so that
/// D_i(plane) = |distance of the patch centroid to the plane| / rho (plus
/// `normal_mismatch_cost` when the patch normal is incompatible with the plane),
/// D_i(l0) = `no_plane_cost_factor` (the paper's 2 rho), the feature term is
/// F_i(plane) = `feature_weight` * (1 - a2D_i), F_i(l0) = `feature_weight` * a2D_i, and each
/// adjacent pair with different labels costs `smoothness_weight`. With the defaults the
/// data term of a patch near a plane lies in [0, 2] and the feature term in [0, 1].
struct PlaneParams {
  static constexpr std::string_view kSection = "segmenter.planes";

  float inlier_distance_m{0.008f};    ///< rho: patch centroid to plane distance, metres
  float inlier_angle_deg{30.0f};      ///< normal compatibility of an inlier patch
  int min_inlier_patches{50};         ///< kappa (paper 50), in supervoxels
  float max_seed_curvature{0.05f};    ///< candidate patches must be flatter than this
  int max_planes{8};                  ///< stop after this many accepted planes
  float duplicate_angle_deg{5.0f};    ///< a candidate this close to an accepted plane ...
  float duplicate_distance_m{0.02f};  ///< ... and this near it is a duplicate
  /// A plane found on the supervoxels along a fixed one (found before them on the pixel grid,
  /// within duplicate_angle_deg and duplicate_distance_m) keeps its own fit when the two
  /// normals lie within this angle, degrees: its fit to the ring of the support around the
  /// objects follows the table there better. Farther apart, something lying on the plane (a
  /// book's top) has pulled it over, and the fixed plane's fit is taken. 0 = always the fixed
  /// fit; duplicate_angle_deg or more = always the found fit (the behaviour before 2026-12-06).
  float fixed_fit_max_angle_deg{1.0f};
  float smoothness_weight{1.0f};     ///< lambda of the Potts term (per edge)
  float feature_weight{1.0f};        ///< scale of the feature term F
  float no_plane_cost_factor{2.0f};  ///< D(l0) = factor * rho
  int max_expansion_cycles{5};       ///< alpha-expansion sweeps over all labels
  /// Added to D_i(plane) when the patch normal is more than inlier_angle_deg from the plane
  /// normal (in units of rho; 0 = the paper's distance-only data term).
  float normal_mismatch_cost{2.0f};
  /// At most this many seed patches are tried as plane candidates (bounds the O(N) inlier
  /// search per candidate).
  int max_candidate_trials{500};
  /// Radius around a seed patch whose patches give the candidate's initial plane, metres
  /// (0 = the seed patch's own plane, as the paper).
  float seed_neighborhood_m{0.1f};
  /// Accept candidate planes largest first (true) or in the order of their seeds' flatness
  /// (false, the paper's greedy order).
  bool accept_largest_first{true};
  /// Patches with fewer points take no part in plane fitting (they are still labelled).
  int min_patch_points{3};
  /// Refit iterations: inliers are re-collected with the refitted plane this many times.
  int refit_iterations{2};

  /// @throws std::invalid_argument naming the key (`segmenter.planes.<field>`) and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::optimize
