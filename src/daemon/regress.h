#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace clutterseg::daemon {

/// Tolerances of a regression comparison between two recorded runs.
struct RegressOptions {
  double centroid_tol_m{0.01};  ///< matched objects' centroids may differ this much, metres
  double min_iou{0.9};          ///< every frame's mean matched-mask IoU must reach this
  std::string objects_channel{"CLUTTERSEG_OBJECTS"};
  std::string labels_channel{"CLUTTERSEG_LABELS"};
};

/// Comparison of one frame present in both runs.
struct FrameComparison {
  int64_t frame_seq{0};
  int objects_a{0};
  int objects_b{0};
  int matched{0};                    ///< pairs within centroid_tol_m
  double max_centroid_error_m{0.0};  ///< over greedy nearest pairs
  double mean_iou{1.0};  ///< over objects of both frames (unmatched count as 0); -1 = no labels
  bool ok{true};
  std::string problem;  ///< why not ok
};

/// Result of comparing two logs.
struct RegressReport {
  std::vector<FrameComparison> frames;  ///< frames present in both, by frame_seq
  std::vector<int64_t> only_in_a;
  std::vector<int64_t> only_in_b;
  bool ok{true};
  /// A multi-line human-readable report.
  std::string ToString(const RegressOptions& options) const;
};

/// Reads two LCM logs (objects_t and label_image_t channels), pairs frames by frame_seq,
/// matches objects greedily by nearest centroid and compares counts, centroids and label
/// masks. @throws std::runtime_error naming the file when a log cannot be read or decoded, or
/// is not whole (a torn or damaged event: named with its byte offset).
RegressReport CompareLogs(const std::string& log_a, const std::string& log_b,
                          const RegressOptions& options);

}  // namespace clutterseg::daemon
