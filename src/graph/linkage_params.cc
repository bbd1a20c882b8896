#include "clutterseg/graph/linkage_params.h"

#include "clutterseg/core/param_check.h"

namespace clutterseg::graph {

void LinkageParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("concavity_tolerance_deg", concavity_tolerance_deg, 0.f, 180.f, "deg");
  check.InRange("extended_convexity_k", extended_convexity_k, 1, 64);
  check.InRange("convexity_epsilon", convexity_epsilon, 0.f, 2.f);
  check.InRange("min_segment_supervoxels", min_segment_supervoxels, 1, 1000000);
  check.InRange("sanity_min_angle_deg", sanity_min_angle_deg, 0.f, 180.f, "deg");
  check.InRange("depth_jump_rel", depth_jump_rel, 0.f, 10.f);
  check.InRange("depth_jump_fraction", depth_jump_fraction, 0.f, 1.f);
  check.InRange("depth_jump_min_pairs", depth_jump_min_pairs, 1, 1000000);
  check.InRange("crease_min_angle_deg", crease_min_angle_deg, 0.f, 180.f, "deg");
  check.InRange("color_threshold", color_threshold, 0.f, 1000.f);
  check.InRange("color_min_angle_deg", color_min_angle_deg, 0.f, 180.f, "deg");
  check.InRange("color_concavity_tolerance_deg", color_concavity_tolerance_deg, 0.f, 180.f, "deg");
  check.InRange("bridge_max_edges", bridge_max_edges, 0, 64, "(0 = off)");
  check.InRange("bridge_min_crease_ratio", bridge_min_crease_ratio, 0.f, 1000.f);
  check.InRange("bridge_min_supervoxels", bridge_min_supervoxels, 1, 1000000);
  check.InRange("bridge_max_angle_deg", bridge_max_angle_deg, 0.f, 180.f, "deg");
  check.InRange("bridge_max_concave_share", bridge_max_concave_share, 0.f, 1.f);
  check.InRange("contact_cut_max_pairs", contact_cut_max_pairs, 0, 1000000, "(0 = off)");
  check.InRange("contact_cut_max_angle_deg", contact_cut_max_angle_deg, 0.f, 90.f, "deg");
  check.InRange("contact_cut_min_supervoxels", contact_cut_min_supervoxels, 1, 1000000);
}

}  // namespace clutterseg::graph
