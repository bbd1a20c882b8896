// Hand-eye extrinsics in the YAML that ROS tools write (tf transforms, easy_handeye's
// calibration files), and every way such a file is refused.
#include "clutterseg/config/extrinsics.h"

#include <cmath>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "clutterseg/config/key_table.h"
#include "tests/testing/test_data.h"

namespace clutterseg::config {
namespace {

std::string Write(const std::string& name, const std::string& text) {
  const std::string path = (testing::ScratchDir("extrinsics_yaml") / name).string();
  std::FILE* f = std::fopen(path.c_str(), "w");
  EXPECT_NE(f, nullptr);
  std::fputs(text.c_str(), f);
  std::fclose(f);
  return path;
}

// What ReadExtrinsicsYaml says about `text`, "" when it accepts it.
std::string ErrorOf(const std::string& name, const std::string& text) {
  const std::string path = Write(name, text);
  try {
    ReadExtrinsicsYaml(path);
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << "the message names the file: " << what;
    return what;
  }
  return "";
}

// A tf transform as `ros2 topic echo /tf_static` prints one (a half turn about x, then a
// small yaw: a camera looking down).
std::string Tf(const std::string& translation = "{x: 0.42, y: -0.1, z: 0.85}",
               const std::string& rotation = "{x: 0.98480775, y: 0.0, z: 0.0, w: -0.17364818}") {
  return "header:\n  stamp:\n    sec: 1700000000\n    nanosec: 0\n  frame_id: base_link\n"
         "child_frame_id: camera_depth_optical_frame\ntransform:\n  translation: " +
         translation + "\n  rotation: " + rotation + "\n";
}

// easy_handeye's ~/.ros/easy_handeye/NAME.yaml (yaml.dump of HandeyeCalibration.to_dict).
std::string EasyHandeye(const std::string& eye_on_hand = "false", const std::string& qw = "0.5") {
  return "parameters:\n  eye_on_hand: " + eye_on_hand +
         "\n  freehand_robot_movement: false\n  move_group: manipulator\n"
         "  move_group_namespace: /\n  namespace: /my_eob_calib_eye_on_base/\n"
         "  robot_base_frame: base_link\n  robot_effector_frame: tool0\n"
         "  tracking_base_frame: camera_color_optical_frame\n  tracking_marker_frame: marker\n"
         "transformation:\n  qw: " +
         qw + "\n  qx: -0.5\n  qy: 0.5\n  qz: -0.5\n  x: 0.9\n  y: 0.05\n  z: 0.6\n";
}

TEST(ExtrinsicsYaml, ReadsATfTransform) {
  const core::Extrinsics e = ReadExtrinsicsYaml(Write("tf.yaml", Tf()));
  EXPECT_EQ(e.parent_frame, "base_link");
  EXPECT_EQ(e.child_frame, "camera_depth_optical_frame");
  EXPECT_DOUBLE_EQ(e.translation_m[0], 0.42);
  EXPECT_DOUBLE_EQ(e.translation_m[1], -0.1);
  EXPECT_DOUBLE_EQ(e.translation_m[2], 0.85);
  EXPECT_NEAR(e.rotation_xyzw[0], 0.98480775, 1e-7);
  EXPECT_NEAR(e.rotation_xyzw[3], -0.17364818, 1e-7);
  // Normalised: the file's quaternion is unit to 1e-8 only.
  double norm = 0.0;
  for (double q : e.rotation_xyzw) norm += q * q;
  EXPECT_NEAR(norm, 1.0, 1e-12);
  // A top-level frame_id, as static transform files of some tools have it.
  const core::Extrinsics flat =
      ReadExtrinsicsYaml(Write("flat.yaml",
                               "frame_id: world\ntransform:\n  translation: {x: 0, y: 0, z: 1}\n"
                               "  rotation: {x: 0, y: 0, z: 0, w: 1}\n"));
  EXPECT_EQ(flat.parent_frame, "world");
  EXPECT_EQ(flat.child_frame, "");
}

TEST(ExtrinsicsYaml, ReadsEasyHandeyesCalibrationFile) {
  const core::Extrinsics base = ReadExtrinsicsYaml(Write("eob.yaml", EasyHandeye()));
  EXPECT_EQ(base.parent_frame, "base_link");  // eye on base: the robot's base
  EXPECT_EQ(base.child_frame, "camera_color_optical_frame");
  EXPECT_DOUBLE_EQ(base.translation_m[0], 0.9);
  EXPECT_DOUBLE_EQ(base.translation_m[2], 0.6);
  EXPECT_DOUBLE_EQ(base.rotation_xyzw[0], -0.5);
  EXPECT_DOUBLE_EQ(base.rotation_xyzw[1], 0.5);
  EXPECT_DOUBLE_EQ(base.rotation_xyzw[2], -0.5);
  EXPECT_DOUBLE_EQ(base.rotation_xyzw[3], 0.5);
  const core::Extrinsics hand = ReadExtrinsicsYaml(Write("eih.yaml", EasyHandeye("true")));
  EXPECT_EQ(hand.parent_frame, "tool0");  // eye in hand: the effector
}

TEST(ExtrinsicsYaml, RefusesEveryBadFileNamingTheField) {
  struct Case {
    const char* name;
    std::string text;
    const char* expected;  // in the message
  };
  const Case cases[] = {
      {"no_transform.yaml", "header: {frame_id: base_link}\n", "'transform'"},
      {"no_rotation.yaml",
       "header: {frame_id: base_link}\ntransform:\n  translation: {x: 0, y: 0, z: 0}\n",
       "'transform.rotation'"},
      {"no_w.yaml", Tf("{x: 0, y: 0, z: 0}", "{x: 0, y: 0, z: 0}"), "'transform.rotation.w'"},
      {"text_y.yaml", Tf("{x: 0, y: left, z: 0}"), "'transform.translation.y' = 'left'"},
      {"nan.yaml", Tf("{x: .nan, y: 0, z: 0}"), "'transform.translation.x' = .nan is not finite"},
      {"inf.yaml", Tf("{x: 0, y: 0, z: 0}", "{x: 0, y: 0, z: .inf, w: 1}"),
       "'transform.rotation.z' = .inf is not finite"},
      {"not_unit.yaml", Tf("{x: 0, y: 0, z: 0}", "{x: 0, y: 0, z: 0.1, w: 1}"),
       "'transform.rotation' has norm 1.00498756: not a unit quaternion"},
      {"zero_q.yaml", Tf("{x: 0, y: 0, z: 0}", "{x: 0, y: 0, z: 0, w: 0}"),
       "not a unit quaternion"},
      {"millimetres.yaml", Tf("{x: 420, y: -100, z: 850}"),
       "'transform.translation' is 953.36247 m from the origin: expected at most 100 m"},
      {"no_frame.yaml",
       "transform:\n  translation: {x: 0, y: 0, z: 0}\n  rotation: {x: 0, y: 0, z: 0, w: 1}\n",
       "'header.frame_id' (or 'parent_frame') is missing or empty"},
      {"eh_no_qw.yaml",
       "parameters: {robot_base_frame: base}\ntransformation: {x: 0, y: 0, z: 0, qx: 0, qy: 0, "
       "qz: 0}\n",
       "'transformation.qw' is missing"},
      {"eh_not_unit.yaml", EasyHandeye("false", "0.6"),
       "'transformation' (qx, qy, qz, qw) has norm"},
      {"eh_no_params.yaml", "transformation: {x: 0, y: 0, z: 0, qx: 0, qy: 0, qz: 0, qw: 1}\n",
       "'parameters' is missing"},
      {"eh_bad_flag.yaml", EasyHandeye("perhaps"), "'parameters.eye_on_hand' is not true"},
      {"eh_no_base.yaml",
       "parameters: {robot_effector_frame: tool0}\ntransformation: {x: 0, y: 0, z: 0, qx: 0, "
       "qy: 0, qz: 0, qw: 1}\n",
       "'parameters.robot_base_frame' is missing or empty"},
      {"list.yaml", "- 1\n- 2\n", "expected a mapping"},
      {"two_docs.yaml", Tf() + "---\n" + Tf(),
       "line 10: a second YAML document; an extrinsics file holds one"},
      {"syntax.yaml", "transform: {translation: [\n", "line "},
  };
  for (const Case& c : cases) {
    const std::string error = ErrorOf(c.name, c.text);
    EXPECT_NE(error.find(c.expected), std::string::npos)
        << c.name << ": expected '" << c.expected << "' in '" << error << "'";
    EXPECT_NE(error.find("extrinsics"), std::string::npos) << error;
  }
  EXPECT_THROW(ReadExtrinsicsYaml("/nonexistent/extrinsics.yaml"), ConfigError);
}

}  // namespace
}  // namespace clutterseg::config
