#include "clutterseg/graph/linkage_params.h"

#include "clutterseg/core/param_check.h"

namespace clutterseg::graph {

void LinkageParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("concavity_tolerance_deg", concavity_tolerance_deg, 0.f, 180.f, "deg");
  check.InRange("extended_convexity_k", extended_convexity_k, 1, 64);
  check.InRange("convexity_epsilon", convexity_epsilon, 0.f, 2.f);
  check.InRange("min_segment_supervoxels", min_segment_supervoxels, 1, 1000000);
}

}  // namespace clutterseg::graph
