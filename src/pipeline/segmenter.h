#pragma once

#include <chrono>
#include <cstdint>
#include <memory>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::pipeline {

/// Segments one organized frame into objects and support planes with the method of
/// docs/method.md (supervoxels, patch features, local area linkage with convexity, plane
/// hypotheses, alpha-expansion, refinement).
///
/// Thread-safety: one Segmenter processes one frame at a time (Process is not reentrant);
/// use one Segmenter per pipeline stage slot. Work inside a frame goes through the injected
/// ThreadPool; results are identical for any pool size. Work buffers are kept between calls,
/// so steady-state processing does not allocate.
class Segmenter {
 public:
  Segmenter(const Segmenter&) = delete;
  Segmenter& operator=(const Segmenter&) = delete;

  /// @throws std::invalid_argument when `params` fail validation (naming the key).
  /// `pool` may be null (single-threaded) and must outlive the Segmenter.
  explicit Segmenter(const SegmenterParams& params, core::ThreadPool* pool = nullptr);
  ~Segmenter();

  /// Segments `cloud` (organized, metres, NaN = invalid; colour optional) and fills `result`.
  /// Degenerate input (no valid point, a single plane, noise) yields a valid, possibly empty,
  /// result; it never throws for frame content.
  void Process(const core::PointCloud& cloud, const core::CameraIntrinsics& intrinsics,
               SegmentationResult* result);
  /// Back-projects `depth` (millimetres, 0 = invalid; `color` optional, may be null) straight
  /// into the working cloud and segments it: the same result as DepthToPointCloud followed by
  /// Process, one pass over the pixels fewer.
  void ProcessDepth(const core::DepthImage& depth, const core::ColorImage* color,
                    const core::CameraIntrinsics& intrinsics, SegmentationResult* result);
  /// The cloud the last call segmented: its input restricted to the depth range (objects'
  /// min/max_depth_m), with ProcessDepth's colour. Valid until the next call.
  const core::PointCloud& working_cloud() const;

  const SegmenterParams& params() const;

  /// Changes the pool used by the following Process calls (null: single-threaded). Results do
  /// not depend on it. Lets a caller running several Segmenters at once keep them off a shared
  /// pool while its cores are busy anyway. Not to be called during Process.
  void SetPool(core::ThreadPool* pool);

 private:
  // The stages after the working cloud (impl_->work) is ready; `cloud` is the input.
  void Segment(const core::PointCloud& cloud, const core::CameraIntrinsics& intrinsics,
               uint32_t num_valid, std::chrono::steady_clock::time_point t_start,
               SegmentationResult* result);

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::pipeline
