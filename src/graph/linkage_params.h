#pragma once

namespace clutterseg::graph {

/// Parameters of local area linkage and convexity (docs/method.md sections 2-3).
struct LinkageParams {
  float concavity_tolerance_deg{10.0f};  ///< below this normal angle an edge counts as convex
  bool use_sanity_criterion{true};       ///< LCCP's sanity check on the connection direction
  bool use_extended_convexity{false};    ///< an edge is convex only if common neighbours agree
  /// With extended convexity: a convex edge stays convex only when at least this many common
  /// neighbours form convex triangles with it (LCCP's k; edges without common neighbours are
  /// then cut).
  int extended_convexity_k{1};
  bool use_type_filter{true};      ///< the LAL majority filter on patch types
  bool cut_on_type_change{true};   ///< cut edges whose (filtered) patch types differ
  float convexity_epsilon{0.0f};   ///< slack on (n_i - n_j) . d > 0, dimensionless
  int min_segment_supervoxels{1};  ///< smaller components merge into a neighbour

  /// @throws std::invalid_argument naming the key and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::graph
