#pragma once

#include <optional>
#include <string>

#include "clutterseg/core/extrinsics.h"

namespace clutterseg::daemon {

/// How the frame source is set up beyond its name (key `source`). YAML section `camera`.
/// The device keys apply to a live OpenNI2 camera; the depth scale to directories of depth
/// PNGs; the intrinsics file to every source but the synthetic one. Ranges of the device keys
/// are those of drivers::OpenNI2SourceOptions, checked when the source is made.
struct SourceParams {
  /// camera.serial: open the OpenNI2 device with this serial number ("" = the first device,
  /// or the one `source: device:URI` names). Not with a URI.
  std::string serial;
  int width{640};   ///< camera.width: live depth (and colour) resolution, px
  int height{480};  ///< camera.height
  int fps{30};      ///< camera.fps: live capture rate, frames per second
  /// camera.color: stream colour from a camera / recording, load colour PNGs beside depth.
  bool color{true};
  /// camera.registration: register depth to colour on the device (when it can).
  bool registration{true};
  /// camera.intrinsics_file: a ROS camera_info calibration (*.yaml / *.yml, see
  /// config::ReadCameraInfoYaml) or a JSON file with fx, fy, cx, cy (px) and optionally
  /// width, height (see io::ReadIntrinsicsJson), replacing the source's own intrinsics: a
  /// calibrated camera's instead of those derived from its field of view, a depth-PNG directory's
  /// instead of the *.json found in it, a PCD directory's instead of those fitted to its clouds.
  /// Scaled to the frames' resolution when it is given for another of the same aspect ratio.
  /// "" = the source's own.
  std::string intrinsics_file;
  /// camera.depth_scale_mm: millimetres per unit of a depth PNG: 1 for millimetre PNGs
  /// (Kinect / Xtion / RealSense exports), 0.2 for TUM RGB-D (value / 5000 = metres).
  double depth_scale_mm{1.0};
  /// camera.extrinsics_file: the camera's pose in a parent frame (a robot's base frame, from a
  /// hand-eye calibration): a JSON file {"parent_frame", "translation" [m], "rotation_xyzw"}
  /// (io::ReadExtrinsicsJson) or the YAML of ROS hand-eye tools, tf `transform:` or
  /// easy_handeye (*.yaml / *.yml, config::ReadExtrinsicsYaml). With it, every geometric field
  /// of objects_t is published in that frame (docs/lcm.md). "" = the camera frame.
  std::string extrinsics_file;
  /// camera.decimation: each frame's depth and colour are reduced by this factor in each
  /// direction before anything else (pipeline::DecimateFrame: the median valid depth of each
  /// block, that pixel's colour, the intrinsics scaled), and segmented and published at that
  /// size; segmenter.objects.min_object_points is divided by its square
  /// (pipeline::ForDecimatedFrames). 2 processes a 640x480 camera as 320x240: several cameras
  /// on one host (docs/daemon.md). Frames that carry their own cloud (PCD sources) are
  /// segmented as they are. 1 = full resolution, at most pipeline::kMaxDecimation.
  int decimation{1};

  /// @throws std::invalid_argument naming the key (`camera.<field>`) and value.
  void ValidateOrThrow() const;
};

/// The pose of camera.extrinsics_file (quaternion normalised), unset when it is "".
/// @throws std::invalid_argument "camera.extrinsics_file = 'PATH': PATH: extrinsics: ..." naming
/// the field when the file cannot be read or holds no usable pose (the daemon's exit code 2).
std::optional<core::Extrinsics> LoadExtrinsics(const SourceParams& camera);

}  // namespace clutterseg::daemon
