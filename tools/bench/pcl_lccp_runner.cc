#include "tools/bench/pcl_lccp_runner.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <unordered_set>

#include <pcl/point_types.h>
#include <pcl/segmentation/lccp_segmentation.h>
#include <pcl/segmentation/supervoxel_clustering.h>

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
  const Clock::time_point t0 = Clock::now();
  pcl::SupervoxelClustering<PointT> super(p.voxel_resolution_m, p.seed_resolution_m);
  super.setUseSingleCameraTransform(p.use_single_camera_transform);
  super.setInputCloud(cloud);
  super.setColorImportance(p.color_importance);
  super.setSpatialImportance(p.spatial_importance);
  super.setNormalImportance(p.normal_importance);
  std::map<std::uint32_t, pcl::Supervoxel<PointT>::Ptr> clusters;
  super.extract(clusters);
  std::multimap<std::uint32_t, std::uint32_t> adjacency;
  super.getSupervoxelAdjacency(adjacency);
  times.supervoxels_ms = MsSince(t0);
  times.num_supervoxels = clusters.size();

  const Clock::time_point t1 = Clock::now();
  if (!clusters.empty()) {
    pcl::LCCPSegmentation<PointT> lccp;
    lccp.setConcavityToleranceThreshold(p.concavity_tolerance_deg);
    lccp.setSanityCheck(p.use_sanity_criterion);
    lccp.setSmoothnessCheck(true, p.voxel_resolution_m, p.seed_resolution_m,
                            p.smoothness_threshold);
    lccp.setKFactor(p.use_extended_convexity ? 1 : 0);
    lccp.setInputSupervoxels(clusters, adjacency);
    lccp.setMinSegmentSize(p.min_segment_supervoxels);
    lccp.segment();
    pcl::PointCloud<pcl::PointXYZL>::Ptr labelled = super.getLabeledCloud();
    lccp.relabelCloud(*labelled);
    if (labelled->size() != cloud->size()) {
      throw std::logic_error("PCL labelled cloud size differs from the input");
    }
    std::unordered_set<std::uint32_t> segments;
    for (size_t i = 0; i < cloud->size(); ++i) {
      const PointT& q = (*cloud)[i];
      if (std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z) &&
          (*labelled)[i].label != 0) {
        segments.insert((*labelled)[i].label);
      }
    }
    times.num_segments = segments.size();
  }
  times.lccp_ms = MsSince(t1);
  times.total_ms = MsSince(t0);
  return times;
}

}  // namespace clutterseg::bench
