#include "tools/bench/pcl_lccp_runner.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <unordered_set>
#include <vector>

#include <pcl/point_types.h>

#include "tools/pcl_baseline/lccp.h"

namespace clutterseg::bench {
namespace {

using PointT = pcl::PointXYZRGBA;
using CloudT = pcl::PointCloud<PointT>;
using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

struct PclLccpRunner::Impl {
  pcl_baseline::BaselineParams params;
  CloudT::Ptr cloud;
  std::vector<std::uint32_t> labels;
};

PclLccpRunner::PclLccpRunner(const pcl_baseline::BaselineParams& params)
    : impl_(std::make_unique<Impl>()) {
  params.ValidateOrThrow();
  impl_->params = params;
  impl_->cloud = std::make_shared<CloudT>();
}

PclLccpRunner::~PclLccpRunner() = default;

void PclLccpRunner::SetInput(const core::PointCloud& cloud) {
  CloudT& c = *impl_->cloud;
  c.resize(cloud.size());
  c.width = static_cast<uint32_t>(cloud.width);
  c.height = static_cast<uint32_t>(std::max(cloud.height, 1));
  bool dense = true;
  for (size_t i = 0; i < cloud.size(); ++i) {
    PointT& q = c[i];
    q.x = cloud.xyz[i].x;
    q.y = cloud.xyz[i].y;
    q.z = cloud.xyz[i].z;
    q.rgba = cloud.has_color() ? cloud.rgba[i] : 0xFF000000u;
    dense = dense && core::IsValid(cloud.xyz[i]);
  }
  c.is_dense = dense;
}

PclLccpTimes PclLccpRunner::Run() {
  const pcl_baseline::BaselineParams& p = impl_->params;
  const CloudT::Ptr& cloud = impl_->cloud;
  PclLccpTimes times;
  pcl_baseline::FrameReport report;
  const Clock::time_point t0 = Clock::now();
  pcl_baseline::internal::RunLccp(cloud, p, &impl_->labels, &report);
  times.total_ms = MsSince(t0);
  times.supervoxels_ms = report.stage1_ms;
  times.lccp_ms = report.stage2_ms;
  times.num_supervoxels = report.intermediate_count;
  std::unordered_set<std::uint32_t> segments;
  for (std::uint32_t l : impl_->labels) {
    if (l != 0) segments.insert(l);
  }
  times.num_segments = segments.size();
  return times;
}

}  // namespace clutterseg::bench
