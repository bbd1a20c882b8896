#pragma once

#include <string>

#include "clutterseg/core/types.h"

namespace clutterseg::core {

/// The pose of the depth camera in a parent frame (a robot's base frame, from a hand-eye
/// calibration): a point p_cam in the camera's depth optical frame (x right, y down,
/// z forward, metres) is p_parent = R p_cam + t in the parent frame, R the rotation of the unit
/// quaternion `rotation_xyzw` and t = `translation_m`. The identity (the default) maps the
/// camera frame onto itself.
struct Extrinsics {
  /// Largest |norm - 1| of the quaternion a file may give; it is normalised after the check.
  static constexpr double kMaxQuaternionNormError = 1e-3;
  /// Largest |t| (metres) accepted: a camera of a robot cell is never 100 m from its base.
  static constexpr double kMaxTranslationM = 100.0;

  std::string parent_frame;  ///< the frame the pose is in, e.g. "base_link"
  std::string child_frame;   ///< the camera frame the file names ("" when it names none)
  double translation_m[3]{0.0, 0.0, 0.0};
  double rotation_xyzw[4]{0.0, 0.0, 0.0, 1.0};

  /// "" when the values are usable, else the problem naming the field by the names given
  /// (a file's own spelling): a non-finite number, a quaternion whose norm is more than
  /// kMaxQuaternionNormError from 1, |t| > kMaxTranslationM, an empty parent frame.
  std::string Problem(const std::string& translation_field, const std::string& rotation_field,
                      const std::string& parent_field) const;
  /// Divides the quaternion by its norm (call after Problem() returned "").
  void Normalize();

  bool operator==(const Extrinsics&) const = default;
};

/// A rigid transform in single precision for applying an Extrinsics to many points:
/// Apply(p) = R p + t. Thread-safe (a value).
struct RigidTransform {
  float r[3][3]{{1.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, {0.f, 0.f, 1.f}};  ///< row-major R
  float t[3]{0.f, 0.f, 0.f};                                         ///< metres

  /// R and t of `e` (its quaternion normalised).
  static RigidTransform Of(const Extrinsics& e);
  Vec3f Apply(const Vec3f& p) const {
    return {r[0][0] * p.x + r[0][1] * p.y + r[0][2] * p.z + t[0],
            r[1][0] * p.x + r[1][1] * p.y + r[1][2] * p.z + t[1],
            r[2][0] * p.x + r[2][1] * p.y + r[2][2] * p.z + t[2]};
  }
  /// R v: a direction (normal, axis) without the translation.
  Vec3f Rotate(const Vec3f& v) const {
    return {r[0][0] * v.x + r[0][1] * v.y + r[0][2] * v.z,
            r[1][0] * v.x + r[1][1] * v.y + r[1][2] * v.z,
            r[2][0] * v.x + r[2][1] * v.y + r[2][2] * v.z};
  }
};

}  // namespace clutterseg::core
