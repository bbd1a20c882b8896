#include "clutterseg/pipeline/segmenter_params.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace clutterseg::pipeline {
namespace {
[[noreturn]] void Fail(const char* key, double value, const char* want) {
  std::ostringstream os;
  os << "segmenter parameter objects." << key << " = " << value << " is invalid (" << want << ")";
  throw std::invalid_argument(os.str());
}
}  // namespace

void ObjectParams::ValidateOrThrow() const {
  if (min_object_points < 1) Fail("min_object_points", min_object_points, "expected >= 1");
  if (!(support_min_area_m2 > 0.f && support_min_area_m2 < 1e4f)) {
    Fail("support_min_area_m2", support_min_area_m2, "expected a positive area in m^2");
  }
  if (!(support_snap_distance_m >= 0.f && support_snap_distance_m < 1.f)) {
    Fail("support_snap_distance_m", support_snap_distance_m, "expected in [0, 1) m");
  }
  if (!(below_support_margin_m >= 0.f && below_support_margin_m < 10.f)) {
    Fail("below_support_margin_m", below_support_margin_m, "expected in [0, 10) m");
  }
  if (!(min_depth_m >= 0.f && std::isfinite(min_depth_m))) {
    Fail("min_depth_m", min_depth_m, "expected >= 0 m");
  }
  if (!(max_depth_m > min_depth_m && std::isfinite(max_depth_m))) {
    Fail("max_depth_m", max_depth_m, "expected finite and > min_depth_m");
  }
}

void SegmenterParams::ValidateOrThrow() const {
  supervoxel.ValidateOrThrow();
  linkage.ValidateOrThrow();
  planes.ValidateOrThrow();
  objects.ValidateOrThrow();
}

}  // namespace clutterseg::pipeline
