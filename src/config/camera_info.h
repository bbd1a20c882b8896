#pragma once

#include <string>

#include "clutterseg/core/camera_intrinsics.h"

namespace clutterseg::config {

/// Reads the pinhole intrinsics of a ROS camera_info calibration file (the YAML that
/// camera_calibration and openni2_camera write): `image_width`, `image_height` and
/// `camera_matrix` {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]} in pixels.
/// Distortion coefficients, rectification and projection matrices are not used (depth
/// images of PrimeSense-class cameras are rectified by the device). Thread-safe.
/// @throws ConfigError naming the file and, for a bad field, the field and its value: not a
/// regular file or larger than 1 MiB, YAML syntax, a missing or non-numeric field, a camera
/// matrix that is not 3x3 with a zero skew and last row (0, 0, 1), or intrinsics a camera
/// cannot have (core::CameraIntrinsics::ValidateOrThrow).
core::CameraIntrinsics ReadCameraInfoYaml(const std::string& path);

}  // namespace clutterseg::config
