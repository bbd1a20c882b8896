#include "tools/pcl_baseline/pcl_baseline.h"

#include <time.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/angles.h>
#include <pcl/conversions.h>
#include <pcl/features/integral_image_normal.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/segmentation/comparator.h>
#include <pcl/segmentation/lccp_segmentation.h>
#include <pcl/segmentation/organized_connected_component_segmentation.h>
#include <pcl/segmentation/organized_multi_plane_segmentation.h>
#include <pcl/segmentation/supervoxel_clustering.h>

#include "tools/pcl_baseline/lccp.h"

namespace clutterseg::pcl_baseline {
namespace internal {
namespace {

using PointT = pcl::PointXYZRGBA;
using CloudT = pcl::PointCloud<PointT>;
using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double ProcessCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

bool IsValid(const PointT& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

// Connects two neighbouring pixels when both are off the excluded (plane) labels and closer
// than a fixed distance. PCL 1.13's EuclideanClusterComparator tests its exclude set the
// other way round (it only connects points whose labels ARE in the set), so the organized
// demo's intent is implemented here.
class PlaneExcludingEuclideanComparator : public pcl::Comparator<PointT> {
 public:
  PlaneExcludingEuclideanComparator(const pcl::PointCloud<pcl::Label>* labels,
                                    std::vector<bool> excluded, float distance_threshold_m)
      : labels_(labels),
        excluded_(std::move(excluded)),
        distance_threshold_m_(distance_threshold_m) {}

  bool compare(int idx1, int idx2) const override {
    if (Excluded(idx1) || Excluded(idx2)) return false;
    const float dist = ((*input_)[idx1].getVector3fMap() - (*input_)[idx2].getVector3fMap()).norm();
    return dist < distance_threshold_m_;  // false for NaN points
  }

 private:
  bool Excluded(int idx) const {
    const std::uint32_t label = (*labels_)[idx].label;
    return label < excluded_.size() && excluded_[label];
  }

  const pcl::PointCloud<pcl::Label>* labels_;
  std::vector<bool> excluded_;
  float distance_threshold_m_;
};

CloudT::Ptr LoadInput(const std::filesystem::path& in) {
  pcl::PCLPointCloud2 blob;
  pcl::PCDReader reader;
  if (reader.read(in.string(), blob) < 0) {
    throw std::runtime_error("cannot read PCD file '" + in.string() + "'");
  }
  if (pcl::getFieldIndex(blob, "x") < 0 || pcl::getFieldIndex(blob, "z") < 0) {
    throw std::runtime_error("PCD file '" + in.string() + "' has no x/y/z fields");
  }
  auto cloud = std::make_shared<CloudT>();
  pcl::fromPCLPointCloud2(blob, *cloud);
  if (cloud->empty()) throw std::runtime_error("PCD file '" + in.string() + "' is empty");
  return cloud;
}

// Compacts arbitrary labels (0 = none) to 1..K in order of first appearance.
std::size_t CompactLabels(std::vector<std::uint32_t>* labels) {
  std::unordered_map<std::uint32_t, std::uint32_t> remap;
  for (std::uint32_t& l : *labels) {
    if (l == 0) continue;
    auto [it, inserted] = remap.try_emplace(l, static_cast<std::uint32_t>(remap.size() + 1));
    l = it->second;
  }
  return remap.size();
}

}  // namespace

// Supervoxels + LCCP. Labels are mapped to the original points through the voxel each
// point falls in (SupervoxelClustering::getLabeledCloud looks up the octree leaf of every
// input point, with the same transform as the voxelization); points whose voxel no
// supervoxel claimed, and invalid points, get 0.
void RunLccp(const CloudT::ConstPtr& cloud, const BaselineParams& p,
             std::vector<std::uint32_t>* labels, FrameReport* report) {
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
  report->stage1_ms = MsSince(t0);
  report->intermediate_count = clusters.size();

  const Clock::time_point t1 = Clock::now();
  labels->assign(cloud->size(), 0);
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
      throw std::logic_error("supervoxel labelled cloud size differs from the input");
    }
    for (std::size_t i = 0; i < cloud->size(); ++i) {
      (*labels)[i] = IsValid((*cloud)[i]) ? (*labelled)[i].label : 0;
    }
  }
  report->stage2_ms = MsSince(t1);
}

namespace {

// Organized multi-plane segmentation + Euclidean clusters (PCL's organized segmentation
// demo): planes with more than plane_min_inliers points become label 0, the remaining
// points are grouped by organized connected components with a distance threshold.
void RunPlanesClusters(const CloudT::ConstPtr& cloud, const BaselineParams& p,
                       std::vector<std::uint32_t>* labels, FrameReport* report) {
  if (!cloud->isOrganized()) {
    throw std::runtime_error("planes-clusters needs an organized cloud (height > 1)");
  }
  const Clock::time_point t0 = Clock::now();
  auto normals = std::make_shared<pcl::PointCloud<pcl::Normal>>();
  pcl::IntegralImageNormalEstimation<PointT, pcl::Normal> ne;
  ne.setNormalEstimationMethod(ne.COVARIANCE_MATRIX);
  ne.setMaxDepthChangeFactor(p.normal_max_depth_change_factor);
  ne.setNormalSmoothingSize(p.normal_smoothing_size_px);
  ne.setInputCloud(cloud);
  ne.compute(*normals);

  pcl::OrganizedMultiPlaneSegmentation<PointT, pcl::Normal, pcl::Label> mps;
  mps.setMinInliers(p.plane_min_inliers);
  mps.setAngularThreshold(pcl::deg2rad(p.plane_angular_threshold_deg));
  mps.setDistanceThreshold(p.plane_distance_threshold_m);
  mps.setInputNormals(normals);
  mps.setInputCloud(cloud);
  std::vector<pcl::PlanarRegion<PointT>, Eigen::aligned_allocator<pcl::PlanarRegion<PointT>>>
      regions;
  std::vector<pcl::ModelCoefficients> coefficients;
  std::vector<pcl::PointIndices> inliers;
  auto plane_labels = std::make_shared<pcl::PointCloud<pcl::Label>>();
  std::vector<pcl::PointIndices> label_indices;
  std::vector<pcl::PointIndices> boundaries;
  mps.segmentAndRefine(regions, coefficients, inliers, plane_labels, label_indices, boundaries);
  report->stage1_ms = MsSince(t0);

  const Clock::time_point t1 = Clock::now();
  std::vector<bool> excluded(label_indices.size(), false);
  std::size_t plane_count = 0;
  for (std::size_t i = 0; i < label_indices.size(); ++i) {
    if (label_indices[i].indices.size() > p.plane_min_inliers) {
      excluded[i] = true;
      ++plane_count;
    }
  }
  report->intermediate_count = plane_count;
  if (plane_labels->size() != cloud->size()) {
    // No plane segmentation output (e.g. no valid normals): nothing is excluded.
    plane_labels->assign(cloud->size(), pcl::Label{std::numeric_limits<std::uint32_t>::max()});
  }
  auto comparator = std::make_shared<PlaneExcludingEuclideanComparator>(
      plane_labels.get(), std::move(excluded), p.cluster_distance_threshold_m);
  comparator->setInputCloud(cloud);
  pcl::OrganizedConnectedComponentSegmentation<PointT, pcl::Label> ccs(comparator);
  ccs.setInputCloud(cloud);
  pcl::PointCloud<pcl::Label> cluster_labels;
  std::vector<pcl::PointIndices> cluster_indices;
  ccs.segment(cluster_labels, cluster_indices);

  labels->assign(cloud->size(), 0);
  std::uint32_t next = 1;
  for (const pcl::PointIndices& cluster : cluster_indices) {
    if (cluster.indices.size() < p.min_cluster_points) continue;
    for (const int idx : cluster.indices) {
      if (IsValid((*cloud)[idx])) (*labels)[idx] = next;
    }
    ++next;
  }
  report->stage2_ms = MsSince(t1);
}

void WriteOutput(const std::filesystem::path& out, const CloudT& cloud,
                 const std::vector<std::uint32_t>& labels) {
  pcl::PointCloud<pcl::PointXYZRGBL> result;
  result.resize(cloud.size());
  result.width = cloud.width;
  result.height = cloud.height;
  result.is_dense = cloud.is_dense;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    pcl::PointXYZRGBL& q = result[i];
    q.x = cloud[i].x;
    q.y = cloud[i].y;
    q.z = cloud[i].z;
    q.rgba = cloud[i].rgba;
    q.label = labels[i];
  }
  pcl::PCDWriter writer;
  if (writer.writeBinary(out.string(), result) != 0) {
    throw std::runtime_error("cannot write PCD file '" + out.string() + "'");
  }
}

}  // namespace
}  // namespace internal

Method ParseMethod(const std::string& name) {
  if (name == "lccp") return Method::kLccp;
  if (name == "planes-clusters") return Method::kPlanesClusters;
  throw std::invalid_argument("method must be 'lccp' or 'planes-clusters', got '" + name + "'");
}

std::string MethodName(Method method) {
  return method == Method::kLccp ? "lccp" : "planes-clusters";
}

void BaselineParams::ValidateOrThrow() const {
  auto require = [](bool ok, const char* key, double value) {
    if (!ok) {
      throw std::invalid_argument(std::string("invalid ") + key + ": " + std::to_string(value));
    }
  };
  require(std::isfinite(voxel_resolution_m) && voxel_resolution_m > 0.0f, "voxel_resolution_m",
          voxel_resolution_m);
  require(std::isfinite(seed_resolution_m) && seed_resolution_m > voxel_resolution_m,
          "seed_resolution_m (must exceed voxel_resolution_m)", seed_resolution_m);
  require(std::isfinite(color_importance) && color_importance >= 0.0f, "color_importance",
          color_importance);
  require(std::isfinite(spatial_importance) && spatial_importance >= 0.0f, "spatial_importance",
          spatial_importance);
  require(std::isfinite(normal_importance) && normal_importance >= 0.0f, "normal_importance",
          normal_importance);
  require(concavity_tolerance_deg >= 0.0f && concavity_tolerance_deg <= 180.0f,
          "concavity_tolerance_deg", concavity_tolerance_deg);
  require(smoothness_threshold >= 0.0f && smoothness_threshold <= 1.0f, "smoothness_threshold",
          smoothness_threshold);
  require(normal_max_depth_change_factor > 0.0f, "normal_max_depth_change_factor",
          normal_max_depth_change_factor);
  require(normal_smoothing_size_px > 0.0f, "normal_smoothing_size_px", normal_smoothing_size_px);
  require(plane_min_inliers > 0, "plane_min_inliers", plane_min_inliers);
  require(plane_angular_threshold_deg > 0.0f && plane_angular_threshold_deg < 90.0f,
          "plane_angular_threshold_deg", plane_angular_threshold_deg);
  require(plane_distance_threshold_m > 0.0f, "plane_distance_threshold_m",
          plane_distance_threshold_m);
  require(cluster_distance_threshold_m > 0.0f, "cluster_distance_threshold_m",
          cluster_distance_threshold_m);
}

FrameReport SegmentPcdFile(const std::filesystem::path& in, const std::filesystem::path& out,
                           const BaselineParams& params) {
  params.ValidateOrThrow();
  const internal::CloudT::Ptr cloud = internal::LoadInput(in);

  FrameReport report;
  std::vector<std::uint32_t> labels;
  const internal::Clock::time_point start = internal::Clock::now();
  const double cpu_start = internal::ProcessCpuMs();
  if (params.method == Method::kLccp) {
    internal::RunLccp(cloud, params, &labels, &report);
  } else {
    internal::RunPlanesClusters(cloud, params, &labels, &report);
  }
  report.segment_count = internal::CompactLabels(&labels);
  report.total_ms = internal::MsSince(start);
  report.total_cpu_ms = internal::ProcessCpuMs() - cpu_start;

  for (std::size_t i = 0; i < cloud->size(); ++i) {
    if (!internal::IsValid((*cloud)[i])) continue;
    ++report.valid_points;
    if (labels[i] != 0) ++report.labelled_points;
  }
  internal::WriteOutput(out, *cloud, labels);
  return report;
}

LabelledCloud ReadLabelledPcd(const std::filesystem::path& path) {
  pcl::PointCloud<pcl::PointXYZRGBL> cloud;
  pcl::PCDReader reader;
  if (reader.read(path.string(), cloud) < 0) {
    throw std::runtime_error("cannot read PCD file '" + path.string() + "'");
  }
  LabelledCloud result;
  result.width = cloud.width;
  result.height = cloud.height;
  result.xyz.reserve(cloud.size() * 3);
  result.rgba.reserve(cloud.size());
  result.label.reserve(cloud.size());
  for (const pcl::PointXYZRGBL& q : cloud) {
    result.xyz.insert(result.xyz.end(), {q.x, q.y, q.z});
    result.rgba.push_back(q.rgba);
    result.label.push_back(q.label);
  }
  return result;
}

}  // namespace clutterseg::pcl_baseline
