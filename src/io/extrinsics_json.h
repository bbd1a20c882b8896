#pragma once

#include <string>

#include "clutterseg/core/extrinsics.h"

namespace clutterseg::io {

/// Reads the pose of the camera in a parent frame from a JSON file:
///
///     {"parent_frame": "base_link", "translation": [x, y, z],
///      "rotation_xyzw": [qx, qy, qz, qw], "child_frame": "camera_depth_optical_frame"}
///
/// translation in metres, rotation a unit quaternion; child_frame is optional. The pose maps
/// the camera's depth optical frame into the parent frame (core::Extrinsics). Parsed with the
/// strict reader of the intrinsics files (1 MiB at most, no duplicate keys). The quaternion is
/// returned normalised. Thread-safe.
/// @throws std::runtime_error naming the file and the field: malformed JSON, a missing field,
/// a field of the wrong type or length, a non-unit quaternion (|norm - 1| > 1e-3), a
/// translation beyond core::Extrinsics::kMaxTranslationM, an empty parent_frame.
core::Extrinsics ReadExtrinsicsJson(const std::string& path);

}  // namespace clutterseg::io
