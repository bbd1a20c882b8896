#pragma once

#include <string_view>

namespace clutterseg::graph {

/// Parameters of local area linkage and convexity (docs/method.md sections 2-3).
struct LinkageParams {
  static constexpr std::string_view kSection = "segmenter.linkage";

  /// Below this normal angle a concave edge still counts as convex, degrees (LCCP and the
  /// paper: 10; 35 measured best, docs/method.md).
  float concavity_tolerance_deg{35.0f};
  bool use_sanity_criterion{true};     ///< LCCP's sanity check on the connection direction
  bool use_extended_convexity{false};  ///< an edge is convex only if common neighbours agree
  /// With extended convexity: a convex edge stays convex only when at least this many common
  /// neighbours form convex triangles with it (LCCP's k; edges without common neighbours are
  /// then cut).
  int extended_convexity_k{1};
  bool use_type_filter{true};  ///< the LAL majority filter on patch types
  /// Cut edges whose (filtered) patch types differ (the paper: true; false measured best).
  bool cut_on_type_change{false};
  float convexity_epsilon{0.0f};   ///< slack on (n_i - n_j) . d > 0, dimensionless
  int min_segment_supervoxels{1};  ///< smaller components merge into a neighbour

  /// @throws std::invalid_argument naming the key (`segmenter.linkage.<field>`) and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::graph
