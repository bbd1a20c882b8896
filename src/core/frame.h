#pragma once

#include <cstdint>
#include <string>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"

namespace clutterseg::core {

/// One capture from an RGB-D source: depth (mm) optionally with colour registered to it, or
/// a point cloud.
/// Frames live in a preallocated pool and are reused; assigning one to another reuses the
/// destination's buffers.
struct RgbdFrame {
  int64_t utime{0};          ///< capture time, microseconds (device or file clock)
  uint64_t sequence{0};      ///< frame number from the source, starting at 0
  int64_t receive_utime{0};  ///< steady-clock time the frame entered the process, microseconds
  /// The same moment on the system clock, microseconds since the epoch: the host time of
  /// capture that the published messages carry (utime is the source's own clock).
  int64_t host_utime{0};
  CameraIntrinsics intrinsics;
  DepthImage depth;  ///< millimetres, 0 = invalid
  ColorImage color;  ///< empty when the source has no colour
  /// The source's own points when it has them (PCD files, organized or not): then this cloud
  /// is segmented as it is, and depth / colour are only its image for display and recording.
  /// Empty for cameras and recordings, which deliver depth.
  PointCloud cloud;
  std::string camera_name{"camera"};
};

/// Microseconds on the steady clock (the time base of RgbdFrame::receive_utime).
int64_t SteadyClockMicros();
/// Microseconds since the epoch on the system clock (the time base of RgbdFrame::host_utime).
int64_t SystemClockMicros();

/// Stamps a frame of a recording without its own clock (files, synthetic scenes): frame
/// number `sequence`, capture time sequence * frame_period_us, received now.
void StampReplayFrame(uint64_t sequence, int64_t frame_period_us, const std::string& camera_name,
                      RgbdFrame* frame);

}  // namespace clutterseg::core
