#include "clutterseg/core/extrinsics.h"

#include <cmath>
#include <cstdio>

#include "clutterseg/core/text_and_color.h"

namespace clutterseg::core {
namespace {

std::string Number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

}  // namespace

std::string Extrinsics::Problem(const std::string& translation_field,
                                const std::string& rotation_field,
                                const std::string& parent_field) const {
  static const char* const kAxes[] = {"x", "y", "z", "w"};
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(translation_m[i])) {
      return translation_field + " " + kAxes[i] + " = " + Number(translation_m[i]) +
             " is not a finite number";
    }
  }
  for (int i = 0; i < 4; ++i) {
    if (!std::isfinite(rotation_xyzw[i])) {
      return rotation_field + " " + kAxes[i] + " = " + Number(rotation_xyzw[i]) +
             " is not a finite number";
    }
  }
  const double t =
      std::sqrt(translation_m[0] * translation_m[0] + translation_m[1] * translation_m[1] +
                translation_m[2] * translation_m[2]);
  if (t > kMaxTranslationM) {
    return translation_field + " is " + Number(t) + " m from the origin: expected at most " +
           Number(kMaxTranslationM) + " m (metres, not millimetres)";
  }
  const double norm =
      std::sqrt(rotation_xyzw[0] * rotation_xyzw[0] + rotation_xyzw[1] * rotation_xyzw[1] +
                rotation_xyzw[2] * rotation_xyzw[2] + rotation_xyzw[3] * rotation_xyzw[3]);
  if (std::abs(norm - 1.0) > kMaxQuaternionNormError) {
    return rotation_field + " has norm " + Number(norm) +
           ": not a unit quaternion (x, y, z, w; |norm - 1| <= " + Number(kMaxQuaternionNormError) +
           ")";
  }
  if (parent_frame.empty()) return parent_field + " is missing or empty";
  if (const int at = FirstControlCharacter(parent_frame); at >= 0) {
    return parent_field + " holds a control character at byte " + std::to_string(at) +
           ": not a frame name (it is published as objects_t.frame_id)";
  }
  return "";
}

void Extrinsics::Normalize() {
  const double norm =
      std::sqrt(rotation_xyzw[0] * rotation_xyzw[0] + rotation_xyzw[1] * rotation_xyzw[1] +
                rotation_xyzw[2] * rotation_xyzw[2] + rotation_xyzw[3] * rotation_xyzw[3]);
  if (norm > 0.0) {
    for (double& q : rotation_xyzw) q /= norm;
  }
}

RigidTransform RigidTransform::Of(const Extrinsics& e) {
  Extrinsics n = e;
  n.Normalize();
  const double x = n.rotation_xyzw[0], y = n.rotation_xyzw[1], z = n.rotation_xyzw[2],
               w = n.rotation_xyzw[3];
  const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  RigidTransform out;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out.r[i][j] = static_cast<float>(r[i][j]);
    out.t[i] = static_cast<float>(n.translation_m[i]);
  }
  return out;
}

}  // namespace clutterseg::core
