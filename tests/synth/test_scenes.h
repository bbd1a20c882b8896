#pragma once

#include "clutterseg/synth/pose.h"
#include "clutterseg/synth/scene.h"

namespace clutterseg::synth::testing {

// A scene whose world frame is the camera frame (x right, y down, z forward).
inline Scene CameraFrameScene() {
  Scene scene;
  scene.camera_pose = Pose{};
  return scene;
}

inline Primitive MakePrimitive(PrimitiveKind kind, const Vec3& center, const Vec3& size,
                               uint32_t label) {
  Primitive p;
  p.kind = kind;
  p.pose.translation = center;
  p.size_m = size;
  p.label = label;
  p.color = {static_cast<uint8_t>(40 + 20 * label), 120, 200};
  return p;
}

// An infinite plane through `point` facing the camera (normal -z), i.e. a wall at depth z.
inline Primitive FrontalWall(double z, uint32_t label = 0) {
  return MakePrimitive(PrimitiveKind::kPlane, {0.0, 0.0, z}, {}, label);
}

}  // namespace clutterseg::synth::testing
