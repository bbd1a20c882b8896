#pragma once

#include <cstddef>
#include <memory>

#include "clutterseg/core/point_cloud.h"
#include "tools/pcl_baseline/pcl_baseline.h"

// PCL's supervoxels + LCCP on in-memory frames, for speed comparisons inside
// clutterseg-bench. Only this library links PCL; PCL headers stay in pcl_lccp_runner.cc.
namespace clutterseg::bench {

/// Wall times of one PCL supervoxels + LCCP run, milliseconds (conversion of the input to a
/// PCL cloud excluded, as file I/O is excluded by clutterseg-pcl-baseline).
struct PclLccpTimes {
  double supervoxels_ms{0.0};  ///< SupervoxelClustering::extract + getSupervoxelAdjacency
  double lccp_ms{0.0};         ///< LCCPSegmentation::segment + relabelling of the input points
  double total_ms{0.0};
  size_t num_supervoxels{0};
  size_t num_segments{0};  ///< distinct non-zero labels over the valid points
};

/// Runs pcl::SupervoxelClustering followed by pcl::LCCPSegmentation with the LCCP fields of
/// pcl_baseline::BaselineParams (the same code path as clutterseg-pcl-baseline --method lccp).
///
/// Thread-safety: Run is not reentrant; distinct instances are independent. Single-threaded.
class PclLccpRunner {
 public:
  PclLccpRunner(const PclLccpRunner&) = delete;
  PclLccpRunner& operator=(const PclLccpRunner&) = delete;

  /// @throws std::invalid_argument when `params` fail validation.
  explicit PclLccpRunner(const pcl_baseline::BaselineParams& params);
  ~PclLccpRunner();

  /// Converts `cloud` (organized or not, metres, NaN = invalid) to a PCL cloud; untimed.
  void SetInput(const core::PointCloud& cloud);
  /// Segments the last input and returns the stage times.
  PclLccpTimes Run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::bench
