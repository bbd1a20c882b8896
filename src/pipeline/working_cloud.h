#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"

namespace clutterseg::pipeline {

/// Which points take part in the segmentation: the parameters of the first stage. YAML
/// section `segmenter.points`.
struct PointsParams {
  static constexpr std::string_view kSection = "segmenter.points";

  float min_depth_m{0.3f};  ///< points nearer than this (z) are ignored, metres
  float max_depth_m{3.0f};  ///< points farther than this (z) are ignored, metres

  /// @throws std::invalid_argument naming the key (`segmenter.points.<field>`) and value.
  void ValidateOrThrow() const;
};

/// Output of WorkingCloudBuilder: the cloud every later stage reads.
struct WorkingCloud {
  /// The input's layout (width, height) and point order; points outside the depth range or
  /// with a non-finite coordinate are NaN.
  core::PointCloud cloud;
  uint32_t num_valid{0};  ///< finite points within the depth range
  double time_ms{0.0};    ///< wall time of the Compute that produced it
};

/// The first stage: restricts an input cloud (organized or not) to the depth range, or
/// back-projects a depth image straight into the working cloud.
///
/// Thread-safety: Compute is not reentrant (the output's buffers are reused); distinct
/// instances are independent. Work is split over the pool given at construction in chunks
/// that do not depend on its size: the output is bit-identical for any pool.
class WorkingCloudBuilder {
 public:
  /// `pool` may be null (single-threaded) and must outlive the builder.
  /// @throws std::invalid_argument when `params` fail validation.
  explicit WorkingCloudBuilder(const PointsParams& params, core::ThreadPool* pool = nullptr);

  /// From a cloud (metres, camera frame, NaN = invalid). Its colour is copied when
  /// `keep_color` and the cloud has colour; labels never.
  void Compute(const core::PointCloudView& input, bool keep_color, WorkingCloud* out);
  /// From a depth image (millimetres, 0 = invalid) with `intrinsics`, and its colour when
  /// `color` is non-null and has the depth's size: one pass over the pixels.
  void Compute(const core::DepthImage& depth, const core::ColorImage* color,
               const core::CameraIntrinsics& intrinsics, WorkingCloud* out);

  const PointsParams& params() const { return params_; }

 private:
  const PointsParams params_;
  core::ThreadPool* const pool_;
  std::vector<uint32_t> chunk_valid_;  // valid points per chunk of the restriction
};

}  // namespace clutterseg::pipeline
