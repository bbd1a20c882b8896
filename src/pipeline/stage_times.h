#pragma once

#include <array>
#include <cstddef>
#include <string_view>

namespace clutterseg::pipeline {

/// The stages of Segmenter::Process, in the order they run. The one table of stage names and
/// order: the per-frame times in SegmentationResult, the LCM stage_times_t and status_t, the
/// benchmarks and the stage chart are all read from it.
enum class Stage : int {
  kPoints,           ///< input -> working cloud within the depth range (or depth back-projection)
  kSupport,          ///< large planes found on the pixel grid take their interior points
  kVoxelize,         ///< voxel octree leaves and their 26-adjacency
  kNormals,          ///< voxel normals and curvature
  kSeeding,          ///< supervoxel seeds
  kGrowth,           ///< supervoxel growth, refinement, connectivity, leftovers
  kSupervoxelStats,  ///< per-pixel ids, supervoxel moments, normals and graph
  kFeatures,         ///< patch eigen-features
  kLinkage,          ///< local area linkage, convexity, initial segments
  kPlanes,           ///< plane hypotheses and unary costs
  kExpansion,        ///< alpha-expansion
  kRefine,           ///< support planes to background, objects grouped, label image
  kObjects,          ///< object statistics
};

inline constexpr size_t kNumStages = 13;

/// Name and one-line description of a stage.
struct StageInfo {
  std::string_view name;         ///< short, lower case, no spaces ("voxelize")
  std::string_view description;  ///< for tables and docs
};

/// The stage table, indexed by static_cast<size_t>(Stage).
const std::array<StageInfo, kNumStages>& StageTable();

/// Name of `stage` (StageTable()[stage].name).
std::string_view StageName(Stage stage);

/// Wall times of the stages of one frame, milliseconds; total_ms is the whole Process call.
/// The stages run one after the other except linkage, which runs beside planes and expansion
/// when the segmenter's pool has a free worker (Segmenter): the stage times then add up to
/// more than total_ms by about the linkage's time.
struct StageTimes {
  std::array<double, kNumStages> ms{};
  double total_ms{0.0};

  double& operator[](Stage s) { return ms[static_cast<size_t>(s)]; }
  double operator[](Stage s) const { return ms[static_cast<size_t>(s)]; }
  /// The supervoxelizer's share (voxelize through supervoxel statistics).
  double supervoxels_ms() const;
};

}  // namespace clutterseg::pipeline
