#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

// Reference segmentations computed with the Point Cloud Library, for comparison with
// clutterseg. Only this tool links PCL; PCL headers stay in pcl_baseline.cc.
namespace clutterseg::pcl_baseline {

/// Which PCL pipeline to run.
enum class Method {
  /// pcl::SupervoxelClustering (VCCS) followed by pcl::LCCPSegmentation.
  kLccp,
  /// pcl::OrganizedMultiPlaneSegmentation on integral-image normals, then organized
  /// Euclidean connected components over the points not on a large plane.
  kPlanesClusters,
};

/// Parses "lccp" or "planes-clusters". @throws std::invalid_argument for any other name.
Method ParseMethod(const std::string& name);

/// Name of a method as accepted by ParseMethod().
std::string MethodName(Method method);

/// Parameters of both baselines. The LCCP defaults are those of PCL's LCCP example
/// (examples/segmentation/example_lccp_segmentation.cpp) with extended convexity and the
/// sanity criterion switched on; the planes-clusters defaults are those of PCL's organized
/// segmentation demo (apps/src/organized_segmentation_demo.cpp) except min_cluster_points.
struct BaselineParams {
  Method method{Method::kLccp};

  // --- supervoxels + LCCP ---
  float voxel_resolution_m{0.0075f};
  float seed_resolution_m{0.03f};
  float color_importance{0.0f};
  float spatial_importance{1.0f};
  float normal_importance{4.0f};
  /// Voxelize in PCL's depth-dependent (x/z, y/z, log z) space. PCL's LCCP example turns it
  /// off unless -tvoxel is given, overriding PCL's organized-cloud default.
  bool use_single_camera_transform{false};
  float concavity_tolerance_deg{10.0f};
  /// LCCP smoothness (step) threshold in [0, 1]; 1 disables the check.
  float smoothness_threshold{0.1f};
  bool use_extended_convexity{true};
  bool use_sanity_criterion{true};
  /// LCCP merges segments with fewer supervoxels than this into a neighbour (0 = off).
  std::uint32_t min_segment_supervoxels{0};

  // --- planes + Euclidean clusters ---
  float normal_max_depth_change_factor{0.02f};
  float normal_smoothing_size_px{20.0f};
  std::uint32_t plane_min_inliers{10000};
  float plane_angular_threshold_deg{3.0f};
  float plane_distance_threshold_m{0.02f};
  float cluster_distance_threshold_m{0.01f};
  std::uint32_t min_cluster_points{500};

  /// @throws std::invalid_argument naming the offending field and its value.
  void ValidateOrThrow() const;
};

/// Wall-clock times of one frame (file I/O excluded) and a few counts.
struct FrameReport {
  /// LCCP: supervoxel extraction. Planes-clusters: normal estimation + plane segmentation.
  double stage1_ms{0.0};
  /// LCCP: LCCP segmentation and relabelling to input points. Planes-clusters: clustering.
  double stage2_ms{0.0};
  double total_ms{0.0};
  /// Process CPU time over the same span as total_ms: close to the wall time an unloaded
  /// machine would show, since both pipelines run on one thread.
  double total_cpu_ms{0.0};
  /// LCCP: number of supervoxels. Planes-clusters: number of planes excluded.
  std::size_t intermediate_count{0};
  /// Number of distinct non-zero output labels.
  std::size_t segment_count{0};
  std::size_t valid_points{0};
  /// Valid points that received a non-zero label.
  std::size_t labelled_points{0};
};

/// An organized labelled cloud as written by SegmentPcdFile(), for inspection.
struct LabelledCloud {
  std::uint32_t width{0};
  std::uint32_t height{0};
  std::vector<float> xyz;  ///< 3 floats per point, metres, camera frame; NaN = invalid.
  std::vector<std::uint32_t> rgba;
  std::vector<std::uint32_t> label;  ///< 0 = no segment.
};

/// Reads the PCD `in` (any field layout with x y z and rgb/rgba; other fields such as label
/// are ignored), segments it with `params.method` and writes `out` as a binary PCD with
/// fields x y z rgba label, the same width, height and point order as `in`; label 0 marks
/// points in no segment (invalid points, unassigned voxels, support planes, small clusters).
/// Labels are compacted to 1..K in order of first appearance in point order.
/// Single-threaded and keeps no state between calls (concurrent calls are untested).
/// @throws std::runtime_error naming the file when it cannot be read or written.
/// @throws std::invalid_argument when params are invalid.
FrameReport SegmentPcdFile(const std::filesystem::path& in, const std::filesystem::path& out,
                           const BaselineParams& params);

/// Reads a PCD written by SegmentPcdFile() (or any PCD with x y z rgba label) through PCL.
/// @throws std::runtime_error naming the file when it cannot be read.
LabelledCloud ReadLabelledPcd(const std::filesystem::path& path);

}  // namespace clutterseg::pcl_baseline
