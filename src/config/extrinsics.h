#pragma once

#include <string>

#include "clutterseg/core/extrinsics.h"

namespace clutterseg::config {

/// Reads the pose of the camera in a parent frame from the YAML that ROS hand-eye tools write,
/// in either of two layouts:
///
/// - a tf transform (geometry_msgs/TransformStamped as `rostopic echo` / `ros2 topic echo`
///   print it, or a static transform file): `header: {frame_id: base_link}`,
///   `child_frame_id: ...`, `transform: {translation: {x, y, z}, rotation: {x, y, z, w}}`;
///   the parent frame may also be a top-level `frame_id` or `parent_frame`;
/// - easy_handeye's calibration file (~/.ros/easy_handeye/NAME.yaml): `transformation: {x, y,
///   z, qx, qy, qz, qw}` and `parameters: {eye_on_hand, robot_base_frame,
///   robot_effector_frame, tracking_base_frame, ...}`; the parent frame is robot_base_frame
///   (eye on base) or robot_effector_frame (eye on hand), the child tracking_base_frame.
///
/// Translation in metres, rotation a unit quaternion; the transform is the child's pose in the
/// parent (p_parent = R p_child + t), and the child must be the depth camera's optical frame
/// (x right, y down, z forward). The quaternion is returned normalised. Thread-safe.
/// @throws ConfigError naming the file and the field: YAML syntax, a second document, a
/// missing or non-numeric field, NaN or infinity, a non-unit quaternion (|norm - 1| > 1e-3),
/// a translation beyond core::Extrinsics::kMaxTranslationM, no parent frame.
core::Extrinsics ReadExtrinsicsYaml(const std::string& path);

}  // namespace clutterseg::config
