#pragma once

#include <array>
#include <cmath>

namespace clutterseg::synth {

/// A 3-D vector in double precision (metres when it is a position). Used for scene
/// description and ray casting, where float would lose sub-millimetre accuracy.
struct Vec3 {
  double x{0.0};
  double y{0.0};
  double z{0.0};
};

inline Vec3 operator+(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator-(const Vec3& a) { return {-a.x, -a.y, -a.z}; }
inline Vec3 operator*(double s, const Vec3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline double Dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 Cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double Norm(const Vec3& a) { return std::sqrt(Dot(a, a)); }
/// `a / |a|`; the zero vector stays zero.
inline Vec3 Normalized(const Vec3& a) {
  const double n = Norm(a);
  return n > 0.0 ? (1.0 / n) * a : a;
}

/// A rigid transform `p_parent = rotation * p_local + translation`. `rotation` is row-major;
/// its columns are the local axes expressed in the parent frame.
struct Pose {
  std::array<double, 9> rotation{1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  Vec3 translation;

  /// Rotates a direction from the local into the parent frame.
  Vec3 Rotate(const Vec3& v) const {
    const auto& r = rotation;
    return {r[0] * v.x + r[1] * v.y + r[2] * v.z, r[3] * v.x + r[4] * v.y + r[5] * v.z,
            r[6] * v.x + r[7] * v.y + r[8] * v.z};
  }
  /// Rotates a direction from the parent into the local frame (transpose).
  Vec3 InverseRotate(const Vec3& v) const {
    const auto& r = rotation;
    return {r[0] * v.x + r[3] * v.y + r[6] * v.z, r[1] * v.x + r[4] * v.y + r[7] * v.z,
            r[2] * v.x + r[5] * v.y + r[8] * v.z};
  }
  /// Maps a local point into the parent frame.
  Vec3 Apply(const Vec3& p) const { return Rotate(p) + translation; }
  /// Maps a parent-frame point into the local frame.
  Vec3 InverseApply(const Vec3& p) const { return InverseRotate(p - translation); }
  /// Local axis `i` (0 = x, 1 = y, 2 = z) in the parent frame.
  Vec3 Axis(int i) const { return {rotation[i], rotation[3 + i], rotation[6 + i]}; }

  /// A pose with the given local axes (orthonormal, right-handed) and origin.
  static Pose FromAxes(const Vec3& x_axis, const Vec3& y_axis, const Vec3& z_axis,
                       const Vec3& origin) {
    Pose p;
    p.rotation = {x_axis.x, y_axis.x, z_axis.x, x_axis.y, y_axis.y,
                  z_axis.y, x_axis.z, y_axis.z, z_axis.z};
    p.translation = origin;
    return p;
  }
  /// Rotation by `yaw_rad` about the parent z axis, then translation.
  static Pose FromYaw(double yaw_rad, const Vec3& origin) {
    const double c = std::cos(yaw_rad);
    const double s = std::sin(yaw_rad);
    return FromAxes({c, s, 0.0}, {-s, c, 0.0}, {0.0, 0.0, 1.0}, origin);
  }
};

}  // namespace clutterseg::synth
