#include "clutterseg/synth/scene.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace clutterseg::synth {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool SamePrimitive(const Primitive& a, const Primitive& b) {
  return a.kind == b.kind && a.pose.rotation == b.pose.rotation &&
         a.pose.translation.x == b.pose.translation.x &&
         a.pose.translation.y == b.pose.translation.y &&
         a.pose.translation.z == b.pose.translation.z && a.size_m.x == b.size_m.x &&
         a.size_m.y == b.size_m.y && a.size_m.z == b.size_m.z && a.label == b.label &&
         a.color.r == b.color.r && a.color.g == b.color.g && a.color.b == b.color.b &&
         a.cap_bottom == b.cap_bottom && a.cap_top == b.cap_top;
}

bool SameScene(const Scene& a, const Scene& b) {
  if (a.primitives.size() != b.primitives.size()) return false;
  for (size_t i = 0; i < a.primitives.size(); ++i) {
    if (!SamePrimitive(a.primitives[i], b.primitives[i])) return false;
  }
  return a.objects.size() == b.objects.size() && a.camera_pose.rotation == b.camera_pose.rotation;
}

// Lowest and highest world z of a primitive (exact for the upright/lying shapes we place).
void PrimitiveZRange(const Primitive& p, double* z0, double* z1) {
  const double cz = p.pose.translation.z;
  double half = 0.0;
  switch (p.kind) {
    case PrimitiveKind::kBox:
      half = 0.5 * p.size_m.z;
      break;
    case PrimitiveKind::kCylinder:
    case PrimitiveKind::kFrustum:
      // Upright: extent along z; lying: radius.
      half = std::abs(p.pose.Axis(2).z) > 0.5 ? 0.5 * p.size_m.z : p.size_m.x;
      break;
    case PrimitiveKind::kSphere:
      half = p.size_m.x;
      break;
    case PrimitiveKind::kHemisphereShell:
      *z0 = cz - p.size_m.x;
      *z1 = cz;
      return;
    case PrimitiveKind::kPlane:
      *z0 = *z1 = cz;
      return;
  }
  *z0 = cz - half;
  *z1 = cz + half;
}

TEST(GenerateScene, SameSeedSameSceneDifferentSeedDifferentScene) {
  const SceneParams params;
  const Scene a = GenerateScene(params, 42);
  const Scene b = GenerateScene(params, 42);
  const Scene c = GenerateScene(params, 43);
  EXPECT_TRUE(SameScene(a, b));
  EXPECT_FALSE(SameScene(a, c));
}

TEST(GenerateScene, LabelsAreConsecutiveAndCountsInRange) {
  SceneParams params;
  params.min_objects = 2;
  params.max_objects = 6;
  int total = 0;
  for (uint64_t seed = 0; seed < 40; ++seed) {
    const Scene s = GenerateScene(params, seed);
    ASSERT_LE(s.objects.size(), 6u);
    total += static_cast<int>(s.objects.size());
    for (size_t i = 0; i < s.objects.size(); ++i) EXPECT_EQ(s.objects[i].label, i + 1);
    std::set<uint32_t> prim_labels;
    for (const Primitive& p : s.primitives) prim_labels.insert(p.label);
    for (uint32_t l = 1; l <= s.objects.size(); ++l) EXPECT_TRUE(prim_labels.count(l)) << l;
    EXPECT_EQ(*prim_labels.rbegin(), s.objects.size());
    EXPECT_TRUE(prim_labels.count(0));  // the table
  }
  // Crowding may drop an object now and then, but not systematically.
  EXPECT_GT(total, 40 * 3);
}

TEST(GenerateScene, ObjectsRestOnTableWithoutInterpenetration) {
  SceneParams params;
  params.min_objects = 6;
  params.max_objects = 10;
  params.touch_probability = 0.4;
  params.stack_probability = 0.2;
  int touching = 0;
  for (uint64_t seed = 0; seed < 60; ++seed) {
    const Scene s = GenerateScene(params, seed);
    for (const SceneObject& a : s.objects) {
      if (a.placement == Placement::kStacked) continue;
      EXPECT_NEAR(a.bottom_z_m, s.table_top_z_m, 1e-12);
      const Footprint& f = a.footprint;
      const double reach = f.shape == Footprint::Shape::kCircle
                               ? f.half_x_m
                               : std::abs(std::cos(f.yaw_rad)) * f.half_x_m +
                                     std::abs(std::sin(f.yaw_rad)) * f.half_y_m;
      EXPECT_LE(std::abs(f.center_x_m) + reach, 0.5 * s.table_width_m + 1e-9);
      for (const SceneObject& b : s.objects) {
        if (b.label <= a.label || b.placement == Placement::kStacked) continue;
        const double d = FootprintDistance(a.footprint, b.footprint);
        const bool pair_touching =
            (b.placement == Placement::kTouching && b.partner_label == a.label);
        if (pair_touching) {
          ++touching;
          EXPECT_GT(d, 0.0) << "seed " << seed;
          EXPECT_LT(d, 0.002) << "seed " << seed;
        } else {
          EXPECT_GE(d, params.min_gap_m - 1e-12)
              << "seed " << seed << " " << a.label << "/" << b.label;
        }
      }
    }
  }
  EXPECT_GT(touching, 10);
}

TEST(GenerateScene, StackedObjectsTouchTheirSupport) {
  SceneParams params;
  params.min_objects = 6;
  params.max_objects = 8;
  params.stack_probability = 0.6;
  params.touch_probability = 0.0;
  params.occlude_probability = 0.0;
  int stacked = 0;
  for (uint64_t seed = 0; seed < 40; ++seed) {
    const Scene s = GenerateScene(params, seed);
    for (const SceneObject& o : s.objects) {
      if (o.placement != Placement::kStacked) continue;
      ++stacked;
      const SceneObject& support = s.objects[o.partner_label - 1];
      EXPECT_TRUE(support.kind == ObjectKind::kBox || support.kind == ObjectKind::kBook);
      // Compare the real primitives: top of the support, bottom of the stacked object.
      double support_top = -1e9, upper_bottom = 1e9;
      for (const Primitive& p : s.primitives) {
        double z0, z1;
        PrimitiveZRange(p, &z0, &z1);
        if (p.label == support.label) support_top = std::max(support_top, z1);
        if (p.label == o.label) upper_bottom = std::min(upper_bottom, z0);
      }
      const double gap = upper_bottom - support_top;
      EXPECT_GE(gap, -1e-9) << "seed " << seed;
      EXPECT_LT(gap, 0.003) << "seed " << seed;
      // Fully supported: the footprint lies inside the support's.
      Footprint shrunk = o.footprint;
      EXPECT_EQ(FootprintDistance(shrunk, support.footprint), 0.0);
    }
  }
  EXPECT_GT(stacked, 10);
}

TEST(GenerateScene, OccludersStandBetweenCameraAndTarget) {
  SceneParams params;
  params.min_objects = 5;
  params.max_objects = 8;
  params.occlude_probability = 0.6;
  params.stack_probability = 0.0;
  params.touch_probability = 0.0;
  int occluding = 0;
  for (uint64_t seed = 0; seed < 30; ++seed) {
    const Scene s = GenerateScene(params, seed);
    const Vec3 eye = s.camera_pose.translation;
    for (const SceneObject& o : s.objects) {
      if (o.placement != Placement::kOccluding) continue;
      ++occluding;
      const SceneObject& target = s.objects[o.partner_label - 1];
      const double d_occ =
          std::hypot(o.footprint.center_x_m - eye.x, o.footprint.center_y_m - eye.y);
      const double d_tgt =
          std::hypot(target.footprint.center_x_m - eye.x, target.footprint.center_y_m - eye.y);
      EXPECT_LT(d_occ, d_tgt);
    }
  }
  EXPECT_GT(occluding, 10);
}

TEST(GenerateScene, CameraLooksDownAtTheTableWithinConfiguredRanges) {
  const SceneParams params;
  for (uint64_t seed = 0; seed < 30; ++seed) {
    const Scene s = GenerateScene(params, seed);
    const Vec3 forward = s.camera_pose.Axis(2);
    const double elevation = std::asin(-forward.z) * 180.0 / kPi;
    EXPECT_GE(elevation, params.camera_elevation_min_deg - 1e-9);
    EXPECT_LE(elevation, params.camera_elevation_max_deg + 1e-9);
    // Distance along the optical axis to the table plane.
    const double t = (s.table_top_z_m - s.camera_pose.translation.z) / forward.z;
    EXPECT_GE(t, params.camera_distance_min_m - 1e-9);
    EXPECT_LE(t, params.camera_distance_max_m + 1e-9);
    // Right-handed, orthonormal.
    const Vec3 x = s.camera_pose.Axis(0), y = s.camera_pose.Axis(1);
    EXPECT_NEAR(Dot(Cross(x, y), forward), 1.0, 1e-12);
  }
}

TEST(GenerateScene, RespectsObjectKinds) {
  SceneParams params;
  params.object_kinds = {ObjectKind::kBottle};
  params.stack_probability = 0.0;
  const Scene s = GenerateScene(params, 5);
  ASSERT_FALSE(s.objects.empty());
  for (const SceneObject& o : s.objects) EXPECT_EQ(o.kind, ObjectKind::kBottle);
  // A bottle is body + shoulder + neck.
  size_t object_prims = 0;
  for (const Primitive& p : s.primitives) object_prims += p.label > 0 ? 1 : 0;
  EXPECT_EQ(object_prims, 3 * s.objects.size());
}

TEST(GenerateScene, InvalidParamsThrowNamingTheKey) {
  SceneParams params;
  params.max_objects = 1;
  params.min_objects = 3;
  try {
    GenerateScene(params, 1);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_objects"), std::string::npos) << e.what();
  }
  SceneParams bad_prob;
  bad_prob.touch_probability = 1.5;
  EXPECT_THROW(GenerateScene(bad_prob, 1), std::invalid_argument);
  SceneParams no_kinds;
  no_kinds.object_kinds.clear();
  EXPECT_THROW(GenerateScene(no_kinds, 1), std::invalid_argument);
}

TEST(GenerateSequence, AddsOneObjectPerFrameKeepingThePrevious) {
  const SceneParams params;
  const int num_frames = 8;
  const std::vector<Scene> seq = GenerateSequence(params, 11, num_frames);
  ASSERT_EQ(seq.size(), static_cast<size_t>(num_frames));
  for (int k = 0; k < num_frames; ++k) {
    const Scene& f = seq[static_cast<size_t>(k)];
    EXPECT_EQ(f.objects.size(), static_cast<size_t>(k)) << "frame " << k;
    EXPECT_EQ(f.camera_pose.rotation, seq[0].camera_pose.rotation);
    for (const Primitive& p : f.primitives) EXPECT_LE(p.label, static_cast<uint32_t>(k));
    if (k == 0) continue;
    // Every primitive of the previous frame is present unchanged.
    const Scene& prev = seq[static_cast<size_t>(k - 1)];
    ASSERT_GE(f.primitives.size(), prev.primitives.size());
    for (size_t i = 0; i < prev.primitives.size(); ++i) {
      EXPECT_TRUE(SamePrimitive(prev.primitives[i], f.primitives[i])) << "frame " << k;
    }
    EXPECT_GT(f.primitives.size(), prev.primitives.size());
  }
  EXPECT_THROW(GenerateSequence(params, 1, 0), std::invalid_argument);
}

TEST(FootprintDistance, CirclesRectanglesAndMixed) {
  Footprint a;
  a.shape = Footprint::Shape::kCircle;
  a.half_x_m = a.half_y_m = 0.05;
  Footprint b = a;
  b.center_x_m = 0.13;
  EXPECT_NEAR(FootprintDistance(a, b), 0.03, 1e-12);
  b.center_x_m = 0.09;
  EXPECT_EQ(FootprintDistance(a, b), 0.0);

  Footprint r;  // 0.2 x 0.1 rectangle rotated by 90 degrees
  r.half_x_m = 0.1;
  r.half_y_m = 0.05;
  r.yaw_rad = 0.5 * kPi;
  r.center_x_m = 0.3;
  // Circle at the origin (radius 0.05); the rectangle spans x in [0.25, 0.35].
  EXPECT_NEAR(FootprintDistance(a, r), 0.2, 1e-12);

  Footprint r2;  // axis-aligned 0.1 x 0.1 square at (0, 0.5): corner-to-corner case
  r2.half_x_m = r2.half_y_m = 0.05;
  Footprint r3 = r2;
  r3.center_x_m = 0.2;
  r3.center_y_m = 0.2;
  EXPECT_NEAR(FootprintDistance(r2, r3), std::hypot(0.1, 0.1), 1e-12);
  // A cross shape: overlapping rectangles with no corner inside the other.
  Footprint long_x;
  long_x.half_x_m = 0.3;
  long_x.half_y_m = 0.01;
  Footprint long_y = long_x;
  long_y.yaw_rad = 0.5 * kPi;
  EXPECT_EQ(FootprintDistance(long_x, long_y), 0.0);
  // A square rotated by 45 degrees next to an axis-aligned one.
  Footprint diamond = r2;
  diamond.yaw_rad = 0.25 * kPi;
  diamond.center_x_m = 0.05 + 0.05 * std::sqrt(2.0) + 0.01;
  EXPECT_NEAR(FootprintDistance(r2, diamond), 0.01, 1e-12);
}

}  // namespace
}  // namespace clutterseg::synth
