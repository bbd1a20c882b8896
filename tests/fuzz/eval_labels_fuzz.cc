// libFuzzer target for the labelled clouds a user hands clutterseg-eval (ground truth and
// prediction, PCD files with a `label` field): io::ReadPcdFromMemory, then
// eval::FrameEvaluator under every ground-truth convention, scoring the cloud's labels
// against themselves and against a relabelled copy. Invariants: every ratio is finite and in
// 0..1, and a prediction equal to the ground truth (convention "plain") scores wov = tp = 1,
// fp = fn = 0 whenever the frame has an object.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/eval/metrics.h"
#include "clutterseg/io/pcd.h"
#include "tests/fuzz/fuzz_check.h"

namespace {

namespace eval = clutterseg::eval;

bool Ratio(double v) { return std::isfinite(v) && v >= 0.0 && v <= 1.0; }

void CheckRatios(const eval::FrameMetrics& m) {
  CLUTTERSEG_FUZZ_CHECK(Ratio(m.wov) && Ratio(m.tp) && Ratio(m.fp) && Ratio(m.fn));
  CLUTTERSEG_FUZZ_CHECK(Ratio(m.precision) && Ratio(m.recall) && Ratio(m.f1));
  CLUTTERSEG_FUZZ_CHECK(m.num_valid_points <= m.num_points);
  CLUTTERSEG_FUZZ_CHECK(m.objects.size() == static_cast<size_t>(m.num_gt_objects));
  CLUTTERSEG_FUZZ_CHECK(m.scored == (m.num_gt_objects > 0));
  for (const eval::ObjectScore& o : m.objects) {
    CLUTTERSEG_FUZZ_CHECK(Ratio(o.overlap) && Ratio(o.tp) && Ratio(o.fp) && Ratio(o.fn));
    CLUTTERSEG_FUZZ_CHECK(o.intersection <= o.size);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  clutterseg::io::ReadLimits limits;
  limits.max_points = size_t{1} << 18;
  clutterseg::core::PointCloud gt;
  try {
    gt = clutterseg::io::ReadPcdFromMemory(data, size, "fuzz", limits);
  } catch (const std::runtime_error&) {
    return 0;
  }
  if (gt.label.size() != gt.xyz.size()) return 0;  // clutterseg-eval refuses it, naming it
  clutterseg::core::PointCloud shifted = gt;
  for (uint32_t& l : shifted.label) l = l % 7 == 0 ? 0 : l / 3;  // merges and drops segments
  eval::FrameMetrics m;
  for (const eval::GtConvention c : {eval::GtConvention::kPlain, eval::GtConvention::kMosdParts,
                                     eval::GtConvention::kMosdObjects, eval::GtConvention::kOcid}) {
    eval::EvalParams params;
    params.gt_convention = c;
    eval::FrameEvaluator evaluator(params);
    evaluator.Evaluate(gt, gt, &m);
    CheckRatios(m);
    if (c == eval::GtConvention::kPlain && m.scored) {
      CLUTTERSEG_FUZZ_CHECK(m.wov == 1.0 && m.tp == 1.0 && m.fp == 0.0 && m.fn == 0.0);
    }
    evaluator.Evaluate(gt, shifted, &m);
    CheckRatios(m);
  }
  return 0;
}
