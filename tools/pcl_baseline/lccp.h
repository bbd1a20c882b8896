#pragma once

// The PCL-facing part of the supervoxels + LCCP baseline, for code that already holds a PCL
// cloud (clutterseg-bench times it beside clutterseg in one process). Includes PCL headers:
// only PCL-linked targets include this file.

#include <cstdint>
#include <vector>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "tools/pcl_baseline/pcl_baseline.h"

namespace clutterseg::pcl_baseline::internal {

/// Supervoxels + LCCP on `cloud`: fills one label per point (0 = no segment or an invalid
/// point), report->stage1_ms (supervoxel extraction and adjacency), stage2_ms (LCCP and
/// relabelling) and intermediate_count (supervoxels).
void RunLccp(const pcl::PointCloud<pcl::PointXYZRGBA>::ConstPtr& cloud, const BaselineParams& p,
             std::vector<std::uint32_t>* labels, FrameReport* report);

}  // namespace clutterseg::pcl_baseline::internal
