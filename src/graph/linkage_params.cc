#include "clutterseg/graph/linkage_params.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace clutterseg::graph {
namespace {

[[noreturn]] void Fail(const char* key, const std::string& value, const char* why) {
  throw std::invalid_argument(std::string("linkage.") + key + " = " + value + ": " + why);
}

}  // namespace

void LinkageParams::ValidateOrThrow() const {
  if (!std::isfinite(concavity_tolerance_deg) || concavity_tolerance_deg < 0.f ||
      concavity_tolerance_deg > 180.f) {
    Fail("concavity_tolerance_deg", std::to_string(concavity_tolerance_deg), "must be in [0, 180]");
  }
  if (extended_convexity_k < 1) {
    Fail("extended_convexity_k", std::to_string(extended_convexity_k), "must be >= 1");
  }
  if (!std::isfinite(convexity_epsilon) || convexity_epsilon < 0.f || convexity_epsilon > 2.f) {
    Fail("convexity_epsilon", std::to_string(convexity_epsilon), "must be in [0, 2]");
  }
  if (min_segment_supervoxels < 1) {
    Fail("min_segment_supervoxels", std::to_string(min_segment_supervoxels), "must be >= 1");
  }
}

}  // namespace clutterseg::graph
