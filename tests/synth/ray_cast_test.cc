#include "clutterseg/synth/internal/ray_cast.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "clutterseg/synth/random.h"
#include "clutterseg/synth/scene.h"
#include "test_scenes.h"

namespace clutterseg::synth::internal {
namespace {

using synth::testing::MakePrimitive;

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(Intersect, BoxFrontFaceAndNormal) {
  const Primitive box = MakePrimitive(PrimitiveKind::kBox, {0.0, 0.0, 1.1}, {0.4, 0.3, 0.2}, 1);
  const PreparedPrimitive p = Prepare(box, 0);
  double t;
  Vec3 n;
  ASSERT_TRUE(Intersect(p, {}, {0.1, -0.05, 1.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 1.0, 1e-12);
  EXPECT_NEAR(n.z, -1.0, 1e-12);
  EXPECT_FALSE(Intersect(p, {}, {0.25, 0.0, 1.0}, 1e-6, kInf, &t, &n));  // passes beside
  EXPECT_FALSE(Intersect(p, {}, {0.0, 0.0, 1.0}, 1e-6, 0.9, &t, &n));    // beyond t_max
}

TEST(Intersect, ClosedCylinderSideAndCap) {
  // Upright axis along world z; look at it horizontally along +x and from above along -z.
  const Primitive can =
      MakePrimitive(PrimitiveKind::kCylinder, {1.0, 0.0, 0.0}, {0.05, 0.05, 0.2}, 1);
  const PreparedPrimitive p = Prepare(can, 0);
  double t;
  Vec3 n;
  ASSERT_TRUE(Intersect(p, {}, {1.0, 0.0, 0.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 0.95, 1e-12);
  EXPECT_NEAR(n.x, -1.0, 1e-12);
  ASSERT_TRUE(Intersect(p, {1.02, 0.0, 1.0}, {0.0, 0.0, -1.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 0.9, 1e-12);  // top cap at z = 0.1
  EXPECT_NEAR(n.z, 1.0, 1e-12);
}

TEST(Intersect, OpenCupShowsItsInsideAndBottom) {
  Primitive cup = MakePrimitive(PrimitiveKind::kCylinder, {0.0, 0.0, 0.0}, {0.05, 0.05, 0.2}, 1);
  cup.cap_top = false;
  const PreparedPrimitive p = Prepare(cup, 0);
  double t;
  Vec3 n;
  // Straight down into the opening: the bottom (z = -0.1) seen from inside.
  ASSERT_TRUE(Intersect(p, {0.0, 0.0, 1.0}, {0.0, 0.0, -1.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 1.1, 1e-12);
  // A slanted ray through the opening hits the inner wall on the far side.
  const Vec3 o{-0.04, 0.0, 0.2};
  const Vec3 d{0.5, 0.0, -1.0};  // reaches x = 0.05 at t = 0.18, z = 0.02
  ASSERT_TRUE(Intersect(p, o, d, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 0.18, 1e-12);
  EXPECT_NEAR(n.x, 1.0, 1e-12);  // geometric outward normal; the renderer flips it
}

TEST(Intersect, FrustumRadiusVariesAlongAxis) {
  // r = 0.05 at z = -0.05 and 0.01 at z = +0.05 (a bottle shoulder).
  Primitive f = MakePrimitive(PrimitiveKind::kFrustum, {}, {0.05, 0.01, 0.1}, 1);
  f.cap_bottom = f.cap_top = false;
  const PreparedPrimitive p = Prepare(f, 0);
  double t;
  Vec3 n;
  ASSERT_TRUE(Intersect(p, {-1.0, 0.0, 0.0}, {1.0, 0.0, 0.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 1.0 - 0.03, 1e-12);  // radius 0.03 at z = 0
  EXPECT_LT(n.x, 0.0);
  EXPECT_GT(n.z, 0.0);  // the shoulder faces up
  // Above the narrow end nothing is hit except through the open top.
  EXPECT_FALSE(Intersect(p, {-1.0, 0.0, 0.06}, {1.0, 0.0, 0.0}, 1e-6, kInf, &t, &n));
}

TEST(Intersect, SphereAndBowl) {
  const Primitive s = MakePrimitive(PrimitiveKind::kSphere, {0.0, 0.0, 2.0}, {0.1, 0.1, 0.1}, 1);
  double t;
  Vec3 n;
  ASSERT_TRUE(Intersect(Prepare(s, 0), {}, {0.0, 0.0, 1.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 1.9, 1e-12);
  // Bowl (lower half shell) seen from above: the ray enters the open top and hits the inside.
  const Primitive b =
      MakePrimitive(PrimitiveKind::kHemisphereShell, {0.0, 0.0, 0.0}, {0.1, 0.1, 0.1}, 1);
  ASSERT_TRUE(Intersect(Prepare(b, 0), {0.0, 0.0, 1.0}, {0.0, 0.0, -1.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 1.1, 1e-12);
  // From below it is hit on the outside.
  ASSERT_TRUE(Intersect(Prepare(b, 0), {0.0, 0.0, -1.0}, {0.0, 0.0, 1.0}, 1e-6, kInf, &t, &n));
  EXPECT_NEAR(t, 0.9, 1e-12);
  // A horizontal ray above the rim misses.
  EXPECT_FALSE(Intersect(Prepare(b, 0), {-1.0, 0.0, 0.01}, {1.0, 0.0, 0.0}, 1e-6, kInf, &t, &n));
}

TEST(TileBins, CandidatesContainTheNearestPrimitive) {
  // Random scenes: the binned nearest hit equals the brute-force nearest hit for every pixel.
  Rng rng(7);
  std::vector<PreparedPrimitive> prims;
  Scene scene;
  const PrimitiveKind kinds[] = {PrimitiveKind::kBox, PrimitiveKind::kCylinder,
                                 PrimitiveKind::kSphere, PrimitiveKind::kFrustum};
  for (uint32_t i = 0; i < 40; ++i) {
    Primitive p = MakePrimitive(
        kinds[i % 4], {rng.Uniform(-0.6, 0.6), rng.Uniform(-0.5, 0.5), rng.Uniform(0.3, 2.0)},
        {rng.Uniform(0.02, 0.2), rng.Uniform(0.02, 0.2), rng.Uniform(0.02, 0.3)}, i + 1);
    p.pose = Pose::FromYaw(rng.Uniform(0.0, 3.0), p.pose.translation);
    prims.push_back(Prepare(p, i));
  }
  const double f = 300.0, cx = 159.5, cy = 119.5;
  TileBins bins;
  bins.Build(prims, Pose{}, f, f, cx, cy, 320, 240, 0);
  int hits = 0;
  for (int v = 0; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      const Vec3 d{(u - cx) / f, (v - cy) / f, 1.0};
      double best = kInf, t;
      Vec3 n;
      int brute = -1;
      for (size_t i = 0; i < prims.size(); ++i) {
        if (Intersect(prims[i], {}, d, 1e-6, best, &t, &n)) {
          best = t;
          brute = static_cast<int>(i);
        }
      }
      const uint32_t* b;
      const uint32_t* e;
      bins.Candidates(u, v, &b, &e);
      double best2 = kInf;
      int binned = -1;
      for (const uint32_t* it = b; it != e; ++it) {
        if (Intersect(prims[*it], {}, d, 1e-6, best2, &t, &n)) {
          best2 = t;
          binned = static_cast<int>(*it);
        }
      }
      ASSERT_EQ(brute, binned) << u << "," << v;
      hits += brute >= 0;
    }
  }
  EXPECT_GT(hits, 1000);
}

}  // namespace
}  // namespace clutterseg::synth::internal
