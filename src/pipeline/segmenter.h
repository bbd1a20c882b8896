#pragma once

#include <memory>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::pipeline {

/// Segments one frame into objects and support planes with the method of docs/method.md:
/// the stages of StageTable() in order (working cloud, support planes first, supervoxels, patch
/// features, local area linkage with convexity, plane hypotheses, alpha-expansion, refinement,
/// object statistics). Each stage is built once here from its section of the params and the pool.
///
/// Thread-safety: one Segmenter processes one frame at a time (Process is not reentrant);
/// use one Segmenter per frame in flight (FrameRunner does). Work inside a frame goes through
/// the pool given at construction; results are bit-identical for any pool size, including
/// none. Work buffers are kept between calls, so steady-state processing does not allocate.
class Segmenter {
 public:
  Segmenter(const Segmenter&) = delete;
  Segmenter& operator=(const Segmenter&) = delete;

  /// `pool` may be null (single-threaded) and must outlive the Segmenter.
  /// @throws std::invalid_argument when `params` fail validation (naming the key).
  explicit Segmenter(const SegmenterParams& params, core::ThreadPool* pool = nullptr);
  ~Segmenter();

  /// Segments `cloud` (metres, camera frame, NaN = invalid; organized or not; colour
  /// optional) and fills `result`, whose label image has the cloud's layout and point order.
  /// `intrinsics` are those of the camera that took an organized cloud. Degenerate input (no
  /// valid point, a single plane, noise) yields a valid, possibly empty, result; it never
  /// throws for frame content.
  void Process(const core::PointCloudView& cloud, const core::CameraIntrinsics& intrinsics,
               SegmentationResult* result);
  /// Back-projects `depth` (millimetres, 0 = invalid; `color` optional, may be null) straight
  /// into the working cloud and segments it: the same result as DepthToPointCloud followed by
  /// Process, one pass over the pixels fewer.
  void ProcessDepth(const core::DepthImage& depth, const core::ColorImage* color,
                    const core::CameraIntrinsics& intrinsics, SegmentationResult* result);
  /// The cloud the last call segmented: its input restricted to the depth range
  /// (params().points), with ProcessDepth's colour, less the points the support-first step
  /// gave to a large plane (params().support; SegmentationResult::num_support_first_points).
  /// Valid until the next call.
  const core::PointCloud& working_cloud() const;
  /// The depth (z, metres, NaN = invalid) of each point of the working cloud before the
  /// support-first step took the large planes' interiors out: the whole scene a stream's
  /// surface history follows (PartitionPrior::Apply), and the depth the Tracker compares from
  /// one frame to the next (Tracker::Update). Kept only for organized clouds and when
  /// params().partition asks for objects by arrival (arrival_gap_frames > 0); empty otherwise.
  /// Valid until the next call.
  const std::vector<float>& scene_depth() const;

  const SegmenterParams& params() const;

 private:
  // The stages after the working cloud; `cloud` is the one whose points (and colour) the
  // object statistics read.
  void Segment(const core::PointCloudView& cloud, const core::CameraIntrinsics& intrinsics,
               SegmentationResult* result);

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::pipeline
