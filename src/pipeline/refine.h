#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/graph/linkage.h"
#include "clutterseg/graph/patch_features.h"
#include "clutterseg/optimize/planes.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/segmenter_params.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::pipeline {

/// Refinement (docs/method.md section 6): support planes become background, the remaining
/// supervoxels are grouped into objects by the initial segments (restricted to foreground and
/// re-split where removing the background disconnected them), pieces of one non-support plane
/// that touch are merged, and groups smaller than min_object_points are dropped. Object ids
/// are assigned in row-major order of each object's first pixel, so output is deterministic.
///
/// Thread-safety: Compute is not reentrant (reuses work buffers); distinct instances are
/// independent.
class Refiner {
 public:
  /// `pool` may be null (single-threaded) and must outlive the Refiner.
  /// @throws std::invalid_argument when `params` fail validation.
  explicit Refiner(const ObjectParams& params, core::ThreadPool* pool = nullptr);

  /// Writes result->labels (already sized to the frame), result->planes, num_objects
  /// default entries in result->objects (labels 1..num_objects; ObjectExtractor fills their
  /// statistics) and its time in result->times[Stage::kRefine]. The pixel passes run on the
  /// pool; the result does not depend on it.
  void Compute(const core::CameraIntrinsics& intrinsics, const core::PointCloud& cloud,
               const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features,
               const graph::LinkageResult& link, const optimize::PlaneLabeling& planes,
               SegmentationResult* result);

 private:
  int32_t Find(int32_t x);
  bool KeepGroup(const optimize::PlaneLabeling& planes, int32_t g) const;
  void Union(int32_t a, int32_t b);

  const ObjectParams params_;
  core::ThreadPool* const pool_;
  std::vector<int32_t> parent_;
  std::vector<uint8_t> background_;
  std::vector<uint8_t> support_;
  std::vector<double> plane_area_;
  std::vector<uint64_t> group_points_;
  std::vector<core::Vec3f> group_centroid_;
  std::vector<int32_t> group_label_;
  std::vector<int32_t> sv_group_;   // [s + 1]: root of supervoxel s's group + 1, 0 = background
  std::vector<uint32_t> sv_label_;  // [s + 1]: object label of supervoxel s, 0 = none
  std::vector<std::vector<int32_t>> band_groups_;  // groups in order of first pixel, per band
  std::vector<std::vector<uint8_t>> band_seen_;
};

}  // namespace clutterseg::pipeline
