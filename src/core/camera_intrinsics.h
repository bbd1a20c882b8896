#pragma once

#include <string>
#include <string_view>

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

  /// Checks the sizes, that the focal lengths give a field of view a camera can have (10 to
  /// 150 degrees) and that the principal point lies near the image.
  /// @throws std::invalid_argument naming `<section>.<field>` and the value.
  void ValidateOrThrow(std::string_view section = "intrinsics") const;
  /// Scales the intrinsics to another resolution of the same sensor.
  CameraIntrinsics Scaled(int new_width, int new_height) const;
  /// Human readable one-line description.
  std::string ToString() const;
};

/// The intrinsics used by the Kinect / Xtion data sets (fx = fy = 525, 640x480).
inline CameraIntrinsics DefaultKinectIntrinsics() { return CameraIntrinsics{}; }

}  // namespace clutterseg::core
