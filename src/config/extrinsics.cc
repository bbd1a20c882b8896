#include "clutterseg/config/extrinsics.h"

#include <yaml-cpp/yaml.h>

#include "clutterseg/config/internal/yaml_file.h"
#include "clutterseg/config/key_table.h"

namespace clutterseg::config {
namespace {

constexpr const char* kKind = "extrinsics";

[[noreturn]] void Fail(const std::string& path, const std::string& what) {
  internal::FailYamlFile(path, kKind, what);
}

// node[key] as a string, "" when absent; `field` names it in errors.
std::string FrameName(const std::string& path, const YAML::Node& node, const char* key,
                      const std::string& field) {
  if (!node || !node.IsMap()) return "";
  const YAML::Node v = node[key];
  if (!v) return "";
  if (!v.IsScalar()) Fail(path, "'" + field + "' is not a frame name");
  return v.Scalar();
}

// The map at node[key], which must be there.
YAML::Node Section(const std::string& path, const YAML::Node& node, const char* key,
                   const std::string& field) {
  const YAML::Node v = node[key];
  if (!v || !v.IsMap()) Fail(path, "'" + field + "' is missing or not a mapping");
  return v;
}

// The tf layout: transform.{translation,rotation} and the frame ids.
core::Extrinsics ReadTf(const std::string& path, const YAML::Node& doc) {
  core::Extrinsics e;
  const YAML::Node transform = Section(path, doc, "transform", "transform");
  const YAML::Node t = Section(path, transform, "translation", "transform.translation");
  const YAML::Node r = Section(path, transform, "rotation", "transform.rotation");
  static const char* const kXyzw[] = {"x", "y", "z", "w"};
  for (int i = 0; i < 3; ++i) {
    e.translation_m[i] = internal::YamlNumber(path, kKind, t[kXyzw[i]],
                                              std::string("transform.translation.") + kXyzw[i]);
  }
  for (int i = 0; i < 4; ++i) {
    e.rotation_xyzw[i] = internal::YamlNumber(path, kKind, r[kXyzw[i]],
                                              std::string("transform.rotation.") + kXyzw[i]);
  }
  e.parent_frame = FrameName(path, doc["header"], "frame_id", "header.frame_id");
  if (e.parent_frame.empty()) e.parent_frame = FrameName(path, doc, "frame_id", "frame_id");
  if (e.parent_frame.empty()) {
    e.parent_frame = FrameName(path, doc, "parent_frame", "parent_frame");
  }
  e.child_frame = FrameName(path, doc, "child_frame_id", "child_frame_id");
  if (const std::string problem = e.Problem("'transform.translation'", "'transform.rotation'",
                                            "'header.frame_id' (or 'parent_frame')");
      !problem.empty()) {
    Fail(path, problem);
  }
  return e;
}

// easy_handeye's layout: transformation.{x,y,z,qx,qy,qz,qw} and parameters.
core::Extrinsics ReadEasyHandeye(const std::string& path, const YAML::Node& doc) {
  core::Extrinsics e;
  const YAML::Node t = Section(path, doc, "transformation", "transformation");
  static const char* const kT[] = {"x", "y", "z"};
  static const char* const kQ[] = {"qx", "qy", "qz", "qw"};
  for (int i = 0; i < 3; ++i) {
    e.translation_m[i] =
        internal::YamlNumber(path, kKind, t[kT[i]], std::string("transformation.") + kT[i]);
  }
  for (int i = 0; i < 4; ++i) {
    e.rotation_xyzw[i] =
        internal::YamlNumber(path, kKind, t[kQ[i]], std::string("transformation.") + kQ[i]);
  }
  const YAML::Node params = Section(path, doc, "parameters", "parameters");
  bool eye_on_hand = false;
  if (const YAML::Node v = params["eye_on_hand"]) {
    try {
      eye_on_hand = v.as<bool>();
    } catch (const YAML::Exception&) {
      Fail(path, "'parameters.eye_on_hand' is not true or false");
    }
  }
  const char* parent_key = eye_on_hand ? "robot_effector_frame" : "robot_base_frame";
  const std::string parent_field = std::string("parameters.") + parent_key;
  e.parent_frame = FrameName(path, params, parent_key, parent_field);
  e.child_frame = FrameName(path, params, "tracking_base_frame", "parameters.tracking_base_frame");
  if (const std::string problem =
          e.Problem("'transformation' (x, y, z)", "'transformation' (qx, qy, qz, qw)",
                    "'" + parent_field + "'");
      !problem.empty()) {
    Fail(path, problem);
  }
  return e;
}

}  // namespace

core::Extrinsics ReadExtrinsicsYaml(const std::string& path) {
  const YAML::Node doc = internal::LoadYamlFile(path, kKind);
  if (!doc.IsMap()) {
    Fail(path, "expected a mapping with 'transform' (tf) or 'transformation' (easy_handeye)");
  }
  core::Extrinsics e;
  if (doc["transform"]) {
    e = ReadTf(path, doc);
  } else if (doc["transformation"]) {
    e = ReadEasyHandeye(path, doc);
  } else {
    Fail(path,
         "'transform' (tf: translation, rotation) or 'transformation' (easy_handeye: "
         "x, y, z, qx, qy, qz, qw) is missing");
  }
  e.Normalize();
  return e;
}

}  // namespace clutterseg::config
