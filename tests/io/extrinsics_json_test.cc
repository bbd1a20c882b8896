// Extrinsics JSON files and every way one is refused; the pose they give applied to points.
#include "clutterseg/io/extrinsics_json.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "tests/testing/test_data.h"

namespace clutterseg::io {
namespace {

std::string Write(const std::string& name, const std::string& text) {
  const std::string path = (testing::ScratchDir("extrinsics_json") / name).string();
  std::FILE* f = std::fopen(path.c_str(), "w");
  EXPECT_NE(f, nullptr);
  std::fputs(text.c_str(), f);
  std::fclose(f);
  return path;
}

// A quarter turn about z (x -> y) and a shift.
constexpr const char* kGood =
    R"({"parent_frame": "base_link", "translation": [0.5, -0.25, 1.0],
        "rotation_xyzw": [0.0, 0.0, 0.70710678, 0.70710678],
        "child_frame": "camera_depth_optical_frame"})";

TEST(ExtrinsicsJson, ReadsThePoseAndItMapsCameraPointsIntoTheParent) {
  const core::Extrinsics e = ReadExtrinsicsJson(Write("good.json", kGood));
  EXPECT_EQ(e.parent_frame, "base_link");
  EXPECT_EQ(e.child_frame, "camera_depth_optical_frame");
  EXPECT_DOUBLE_EQ(e.translation_m[1], -0.25);
  EXPECT_NEAR(e.rotation_xyzw[2], std::sqrt(0.5), 1e-8);
  // p_parent = R p_cam + t: the camera's x axis becomes the parent's y axis.
  const core::RigidTransform tf = core::RigidTransform::Of(e);
  const core::Vec3f p = tf.Apply(core::Vec3f{1.f, 0.f, 0.f});
  EXPECT_NEAR(p.x, 0.5f, 1e-6f);
  EXPECT_NEAR(p.y, 0.75f, 1e-6f);
  EXPECT_NEAR(p.z, 1.0f, 1e-6f);
  const core::Vec3f q = tf.Rotate(core::Vec3f{0.f, 0.f, 2.f});
  EXPECT_NEAR(q.z, 2.f, 1e-6f);
  // Without child_frame.
  const core::Extrinsics bare = ReadExtrinsicsJson(Write(
      "bare.json",
      R"({"parent_frame": "world", "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})"));
  EXPECT_EQ(bare.child_frame, "");
}

TEST(ExtrinsicsJson, RefusesEveryBadFileNamingTheField) {
  struct Case {
    const char* name;
    const char* text;
    const char* expected;
  };
  const Case cases[] = {
      {"no_parent.json", R"({"translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "missing key 'parent_frame'"},
      {"empty_parent.json",
       R"({"parent_frame": "", "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "'parent_frame' is missing or empty"},
      {"no_translation.json", R"({"parent_frame": "b", "rotation_xyzw": [0, 0, 0, 1]})",
       "missing key 'translation'"},
      {"no_rotation.json", R"({"parent_frame": "b", "translation": [0, 0, 0]})",
       "missing key 'rotation_xyzw'"},
      {"short.json",
       R"({"parent_frame": "b", "translation": [0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "'translation' must be an array of 3 numbers"},
      {"text.json",
       R"({"parent_frame": "b", "translation": [0, "1", 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "'translation'[1] is not a number"},
      {"null.json",
       R"({"parent_frame": "b", "translation": [0, 0, 0], "rotation_xyzw": [0, 0, null, 1]})",
       "'rotation_xyzw'[2] is not a number"},
      {"not_unit.json",
       R"({"parent_frame": "b", "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 2]})",
       "'rotation_xyzw' has norm 2: not a unit quaternion"},
      {"far.json",
       R"({"parent_frame": "b", "translation": [0, 150, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "'translation' is 150 m from the origin"},
      {"nan.json",
       R"({"parent_frame": "b", "translation": [NaN, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "malformed JSON: line 1, column"},
      {"huge.json",
       R"({"parent_frame": "b", "translation": [1e999, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "number out of range"},
      // A NUL or newline in the frame name: LCM cannot encode it (every objects_t was refused
      // at publish, exit 5 after the run, until the hostile campaign).
      {"nul_frame.json",
       R"({"parent_frame": "base\u0000link", "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "'parent_frame' holds a control character at byte 4"},
      {"newline_frame.json",
       R"({"parent_frame": "base\nlink", "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "'parent_frame' holds a control character at byte 4"},
      {"frame_number.json",
       R"({"parent_frame": 3, "translation": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 1]})",
       "'parent_frame' is not a string"},
      {"twice.json",
       R"({"parent_frame": "b", "parent_frame": "c", "translation": [0, 0, 0],
           "rotation_xyzw": [0, 0, 0, 1]})",
       "duplicate key \"parent_frame\""},
      {"array.json", "[1, 2, 3]", "top level is not a JSON object"},
      {"empty.json", "", "empty file"},
  };
  for (const Case& c : cases) {
    const std::string path = Write(c.name, c.text);
    try {
      ReadExtrinsicsJson(path);
      ADD_FAILURE() << c.name << " was accepted";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_NE(what.find(c.expected), std::string::npos)
          << c.name << ": expected '" << c.expected << "' in '" << what << "'";
    }
  }
  EXPECT_THROW(ReadExtrinsicsJson("/nonexistent/extrinsics.json"), std::runtime_error);
}

}  // namespace
}  // namespace clutterseg::io
