#pragma once

#include <cstdint>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"
#include "clutterseg/synth/scene.h"
#include "clutterseg/synth/sensor_params.h"

namespace clutterseg::synth {

/// Why a depth pixel holds no measurement.
enum class DepthStatus : uint8_t {
  kValid = 0,
  kNoSurface,   ///< the camera ray hits nothing
  kOutOfRange,  ///< outside [min_range_m, max_range_m]
  kShadow,      ///< the projector cannot see the surface point
  kGrazing,     ///< incidence angle beyond max_incidence_deg
  kDropout,     ///< random or edge-cluster dropout
};

/// One rendered sensor frame. All images have the intrinsics' size and are pixel-aligned
/// (colour registered to depth).
struct RenderedFrame {
  core::DepthImage depth;  ///< millimetres, 0 = invalid
  core::ColorImage color;
  /// 0 = background (table, floor, wall) or invalid depth; 1..N = object label.
  core::LabelImage label;
  /// Noise-free depth (metres) of the nearest surface through the pixel centre, 0 when the
  /// ray hits nothing; set whether or not the sensor measures it.
  core::Image<float> true_depth_m;
  /// Label of the nearest surface through the pixel centre (0 for background or no surface),
  /// whether or not the sensor measures it.
  core::LabelImage true_label;
  /// 1 where that surface of an object is seen from inside (its outward normal faces away
  /// from the camera: the inside of a bowl, a cup's inner wall and bottom), else 0.
  core::Image<uint8_t> true_inside;
  /// true_inside where `label` is measured, 0 elsewhere: an object point's part, as mOSD's
  /// part labels separate a vessel's inside from its outside.
  core::Image<uint8_t> inside;
  /// Status of each depth pixel (DepthStatus values).
  core::Image<uint8_t> status;
  core::CameraIntrinsics intrinsics;
};

/// Ray casts `scene` through a pinhole camera at scene.camera_pose and applies the sensor
/// model. `out`'s buffers are reused. Randomness comes from counter-based hashes of
/// (noise_seed, pixel) and, for the spatially correlated axial noise, (noise_seed, noise grid
/// cell), so the output is identical for any `pool` (nullptr = calling thread) and thread
/// count.
/// Thread-safety: reentrant; `out` must not be shared between concurrent calls.
/// Complexity: O(pixels x primitives overlapping the pixel's tile).
/// @throws std::invalid_argument when the intrinsics or sensor params are invalid.
void RenderScene(const Scene& scene, const core::CameraIntrinsics& intrinsics,
                 const SensorParams& sensor, uint64_t noise_seed, RenderedFrame* out,
                 core::ThreadPool* pool = nullptr);

/// Converts a rendered frame to an organized cloud (metres, camera frame): xyz back-projected
/// from the depth image (NaN where invalid), rgba from the colour image, label from the label
/// image. Reuses `cloud`'s storage.
void ToPointCloud(const RenderedFrame& frame, core::PointCloud* cloud);

}  // namespace clutterseg::synth
