#pragma once

#include <string>
#include <string_view>

#include "clutterseg/eval/metrics.h"

namespace clutterseg::eval {

/// One JSON object on a single line (no trailing newline) with the keys "convention",
/// "frames", "frames_scored", "missing", "wov", "precision", "recall", "f1", "tp", "fp",
/// "fn", "gt_objects", "segments", "over_segmented", "under_segmented" (totals over frames)
/// and "mean_gt_objects", "mean_segments", "mean_over_segmented", "mean_under_segmented"
/// (per frame). The quality figures are null when no frame has ground-truth objects.
/// `missing_predictions` counts frames scored as empty because their prediction was absent.
std::string SummaryToJson(const Summary& summary, const EvalParams& params,
                          int missing_predictions = 0);

/// Header line of the per-frame CSV (no trailing newline).
std::string CsvHeader();

/// One per-frame CSV row (no trailing newline); `frame` is quoted when needed. Ratios of an
/// unscored frame (no ground-truth objects) are left empty.
std::string CsvRow(std::string_view frame, const FrameMetrics& metrics, bool missing_prediction);

}  // namespace clutterseg::eval
