#pragma once

#include <string>

namespace clutterseg::core {

/// Pinhole intrinsics of a depth camera, in pixels. Pixel (u, v) at depth z (metres) is the
/// point ((u - cx) * z / fx, (v - cy) * z / fy, z) in the camera frame (x right, y down,
/// z forward).
struct CameraIntrinsics {
  int width{640};
  int height{480};
  double fx{525.0};
  double fy{525.0};
  double cx{319.5};
  double cy{239.5};

  /// @throws std::invalid_argument naming the bad field when a value is out of range.
  void ValidateOrThrow() const;
  /// Scales the intrinsics to another resolution of the same sensor.
  CameraIntrinsics Scaled(int new_width, int new_height) const;
  /// Human readable one-line description.
  std::string ToString() const;
};

/// The intrinsics used by the Kinect / Xtion data sets (fx = fy = 525, 640x480).
inline CameraIntrinsics DefaultKinectIntrinsics() { return CameraIntrinsics{}; }

}  // namespace clutterseg::core
