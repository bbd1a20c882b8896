#pragma once

#include <string_view>

#include "clutterseg/geometry/voxel_grid.h"

namespace clutterseg::supervoxel {

/// Parameters of the octree supervoxelizer (VCCS, docs/method.md section 1). YAML section
/// `segmenter.supervoxel`; the voxel grid's keys (`voxel_resolution_m`,
/// `use_single_camera_transform`) are written in the same section.
struct SupervoxelParams {
  static constexpr std::string_view kSection = "segmenter.supervoxel";

  /// The voxel grid (octree leaves) the supervoxels are grown over.
  geometry::VoxelGridParams grid;
  float seed_resolution_m{0.03f};  ///< spacing of supervoxel seeds, metres
  float color_importance{0.0f};    ///< wc; 0 = geometry only (the paper)
  float spatial_importance{1.0f};  ///< ws
  /// wn (VCCS and PCL's example: 4; 6 measured better on mOSD and the synthetic rooms,
  /// docs/results.md).
  float normal_importance{6.0f};
  /// Re-centre and regrow this many times (VCCS and PCL: several). One pass keeps supervoxels
  /// from straddling creases between stacked objects (tests/pipeline) at about 10% less
  /// supervoxelizer time than two; quality on mOSD is the same for 0, 1 and 2.
  int refinement_iterations{1};
  /// Seeds whose search volume holds fewer voxels than this fraction of a flat disc's are
  /// dropped (the disc's voxel count uses the voxel size at the seed's depth).
  float min_seed_occupancy{0.25f};
  /// Supervoxels grow in this many strips of the image (ranges of voxel x, about equal voxel
  /// counts), each on its own and in parallel: a supervoxel claims voxels of its own strip
  /// only, so none straddles a strip border. 1 = one region (VCCS). The result depends on
  /// this number, never on the number of threads. Two strips halve the growth stage's
  /// latency on two cores with the same quality (mOSD, synthetic); see docs/method.md.
  int growth_regions{2};
  /// At most this many seeds per frame. A frame with more (a wide field of view, a seed
  /// spacing far below the voxel's) keeps every k-th seed in voxel order, spread over the
  /// whole frame, and its supervoxels grow larger; Supervoxels::capped says so. The
  /// supervoxels are the seeds' plus one per isolated piece of surface no seed reaches
  /// (bounded by the voxels). Bounds the time and memory of every later stage.
  int max_supervoxels{50000};

  /// @throws std::invalid_argument naming the key (`segmenter.supervoxel.<field>`) and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::supervoxel
