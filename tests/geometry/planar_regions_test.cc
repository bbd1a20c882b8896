#include "clutterseg/geometry/planar_regions.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/thread_pool.h"
#include "tests/testing/expect_invalid_argument.h"

namespace clutterseg::geometry {
namespace {

constexpr float kNaN = core::kInvalidDepth;

// A Kinect view of a table plane n . p + d = 0 (1 m below and in front of the camera, seen at
// about 40 deg) with Gaussian depth noise, and a box standing on it: the pixels of `box` (u0,
// v0, u1, v1) lie `box_height_m` closer to the camera than the table. Pixels beyond 3 m are
// invalid.
struct Scene {
  core::PointCloud cloud;
  core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  core::Vec3f n;
  float d{0.f};
  std::vector<uint8_t> on_box;  // per pixel
};

Scene TableScene(float noise_m, const int box[4], float box_height_m, uint32_t seed = 1) {
  Scene s;
  const float tilt = 0.7f;  // radians between the optical axis and the table
  s.n = core::Vec3f{0.f, -std::cos(tilt), -std::sin(tilt)};  // towards the camera
  s.d = 0.9f;
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, noise_m);
  s.cloud.width = s.k.width;
  s.cloud.height = s.k.height;
  s.cloud.xyz.assign(static_cast<size_t>(s.k.width) * s.k.height, core::Vec3f{kNaN, kNaN, kNaN});
  s.on_box.assign(s.cloud.xyz.size(), 0);
  for (int v = 0; v < s.k.height; ++v) {
    for (int u = 0; u < s.k.width; ++u) {
      const float rx = static_cast<float>((u - s.k.cx) / s.k.fx);
      const float ry = static_cast<float>((v - s.k.cy) / s.k.fy);
      const float denom = s.n.x * rx + s.n.y * ry + s.n.z;
      if (denom >= 0.f) continue;
      const bool in_box = u >= box[0] && u < box[2] && v >= box[1] && v < box[3];
      const float dd = in_box ? s.d - box_height_m : s.d;
      float z = -dd / denom;
      if (!(z > 0.3f && z < 3.f)) continue;
      z += noise_m > 0.f ? noise(rng) : 0.f;
      const size_t i = static_cast<size_t>(v) * s.k.width + u;
      s.cloud.xyz[i] = core::Vec3f{rx * z, ry * z, z};
      s.on_box[i] = in_box ? 1 : 0;
    }
  }
  return s;
}

float Distance(const core::Vec3f& p, const core::Vec3f& n, float d) {
  return std::abs(n.x * p.x + n.y * p.y + n.z * p.z + d);
}

TEST(PlanarRegions, TakesTheTableInteriorAndLeavesTheBoxWithAMargin) {
  const int box[4] = {280, 260, 360, 340};
  Scene s = TableScene(0.001f, box, 0.08f);
  const core::PointCloud before = s.cloud;
  PlanarRegionParams params;
  PlanarRegionFinder finder(params);
  PlanarRegions out;
  finder.Compute(s.k, 0.15f, &s.cloud, &out);

  ASSERT_EQ(out.regions.size(), 1u);
  const PlanarRegion& r = out.regions[0];
  EXPECT_GT(r.normal.x * s.n.x + r.normal.y * s.n.y + r.normal.z * s.n.z, std::cos(0.01));
  EXPECT_NEAR(r.d, s.d, 0.003f);
  EXPECT_GE(r.area_m2, 0.15f);
  EXPECT_EQ(r.num_taken_points, out.num_taken_points);

  size_t valid = 0, taken = 0, box_taken = 0, near_box_taken = 0;
  double taken_area = 0.0;  // z^2 / (fx fy cos t) per taken point
  for (int v = 0; v < s.k.height; ++v) {
    for (int u = 0; u < s.k.width; ++u) {
      const size_t i = static_cast<size_t>(v) * s.k.width + u;
      if (!core::IsValid(before.xyz[i])) {
        EXPECT_FALSE(core::IsValid(s.cloud.xyz[i]));
        continue;
      }
      ++valid;
      if (core::IsValid(s.cloud.xyz[i])) {
        EXPECT_EQ(s.cloud.xyz[i].z, before.xyz[i].z);  // kept points are untouched
        continue;
      }
      ++taken;
      box_taken += s.on_box[i];
      const core::Vec3f& p = before.xyz[i];
      const double range = std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
      const double cos_t = std::abs(p.x * s.n.x + p.y * s.n.y + p.z * s.n.z) / range;
      taken_area += double{p.z} * p.z / (s.k.fx * s.k.fy * std::max(0.2, cos_t));
      // Taken points lie on the table, within the point bound of the found plane.
      EXPECT_LT(Distance(before.xyz[i], r.normal, r.d), 0.02f);
      const bool near_box = u >= box[0] - params.margin_px && u < box[2] + params.margin_px &&
                            v >= box[1] - params.margin_px && v < box[3] + params.margin_px;
      near_box_taken += near_box ? 1 : 0;
    }
  }
  EXPECT_EQ(taken, out.num_taken_points);
  // The taken area is the taken points' (each cell's pixels counted at its centroid).
  EXPECT_NEAR(r.taken_area_m2, taken_area, 0.01 * taken_area);
  EXPECT_EQ(box_taken, 0u);
  EXPECT_EQ(near_box_taken, 0u) << "the margin around the box stays for the supervoxels";
  // Most of the table goes (the interior), not all of it (the ring around the box).
  EXPECT_GT(static_cast<double>(taken) / valid, 0.6);
  EXPECT_LT(taken, valid - (box[2] - box[0]) * (box[3] - box[1]));
}

TEST(PlanarRegions, TheRingIsMeasuredFromTheObjectsPoints) {
  // Every table point farther than margin_px (in x or in y) from the box goes, wherever the
  // cell boundaries fall; the ones within it all stay.
  const int box[4] = {283, 257, 341, 318};  // not aligned with the cells
  for (const int margin : {4, 10, 20}) {
    Scene s = TableScene(0.001f, box, 0.08f, 3);
    const core::PointCloud before = s.cloud;
    PlanarRegionParams params;
    params.margin_px = margin;
    PlanarRegions out;
    PlanarRegionFinder(params).Compute(s.k, 0.15f, &s.cloud, &out);
    ASSERT_EQ(out.regions.size(), 1u);
    size_t far = 0, far_taken = 0, near_taken = 0;
    for (int v = 0; v < s.k.height; ++v) {
      for (int u = 0; u < s.k.width; ++u) {
        const size_t i = static_cast<size_t>(v) * s.k.width + u;
        if (!core::IsValid(before.xyz[i]) || s.on_box[i]) continue;
        const bool taken = !core::IsValid(s.cloud.xyz[i]);
        const bool near_box = u >= box[0] - margin && u < box[2] + margin && v >= box[1] - margin &&
                              v < box[3] + margin;
        if (near_box) {
          near_taken += taken ? 1 : 0;
        } else {
          ++far;
          far_taken += taken ? 1 : 0;
        }
      }
    }
    EXPECT_EQ(near_taken, 0u) << "margin " << margin;
    // Only points whose noise puts them beyond 3 bounds of the plane stay.
    EXPECT_GT(static_cast<double>(far_taken) / far, 0.999) << "margin " << margin;
  }
}

TEST(PlanarRegions, CellsWithDropoutsGoWithTheirPlane) {
  // A patch of the table with a third of its pixels missing (sensor dropouts): its cells
  // fail the validity test, but their points lie on the table's plane and go with it, and
  // the missing pixels leave no ring.
  const int box[4] = {0, 0, 0, 0};
  Scene s = TableScene(0.001f, box, 0.f, 5);
  std::mt19937 rng(11);
  std::bernoulli_distribution drop(1.0 / 3.0);
  size_t patch_valid = 0;
  for (int v = 300; v < 380; ++v) {
    for (int u = 250; u < 390; ++u) {
      core::Vec3f& p = s.cloud.xyz[static_cast<size_t>(v) * s.k.width + u];
      if (drop(rng)) p = core::Vec3f{kNaN, kNaN, kNaN};
      patch_valid += core::IsValid(p) ? 1 : 0;
    }
  }
  ASSERT_GT(patch_valid, 5000u);
  PlanarRegions out;
  PlanarRegionFinder(PlanarRegionParams{}).Compute(s.k, 0.15f, &s.cloud, &out);
  ASSERT_EQ(out.regions.size(), 1u);
  size_t left = 0;
  for (int v = 300; v < 380; ++v) {
    for (int u = 250; u < 390; ++u) {
      left += core::IsValid(s.cloud.xyz[static_cast<size_t>(v) * s.k.width + u]) ? 1 : 0;
    }
  }
  EXPECT_LT(static_cast<double>(left) / patch_valid, 0.001);
}

TEST(PlanarRegions, LoneSpikesLeaveNoIslandButPairsKeepTheirRing) {
  // Single points far off the table (noise spikes) keep no ring: the table around them goes
  // and only the spike stays. Two touching points keep the ring of margin_px around them.
  const int box[4] = {0, 0, 0, 0};
  Scene s = TableScene(0.001f, box, 0.f, 9);
  const int w = s.k.width;
  auto lift = [&](int u, int v) {
    core::Vec3f& p = s.cloud.xyz[static_cast<size_t>(v) * w + u];
    p = core::Vec3f{p.x * 0.9f, p.y * 0.9f, p.z * 0.9f};  // 10 % nearer: far off the plane
  };
  lift(200, 330);
  lift(420, 360);
  lift(320, 300);
  lift(321, 301);  // a pair (diagonal neighbours)
  const core::PointCloud before = s.cloud;
  PlanarRegionParams params;
  PlanarRegions out;
  PlanarRegionFinder(params).Compute(s.k, 0.15f, &s.cloud, &out);
  ASSERT_EQ(out.regions.size(), 1u);
  auto kept_around = [&](int u0, int v0) {
    size_t kept = 0;
    for (int v = v0 - params.margin_px; v <= v0 + params.margin_px; ++v) {
      for (int u = u0 - params.margin_px; u <= u0 + params.margin_px; ++u) {
        const size_t i = static_cast<size_t>(v) * w + u;
        kept += core::IsValid(before.xyz[i]) && core::IsValid(s.cloud.xyz[i]) ? 1 : 0;
      }
    }
    return kept;
  };
  EXPECT_EQ(kept_around(200, 330), 1u) << "only the spike stays";
  EXPECT_EQ(kept_around(420, 360), 1u) << "only the spike stays";
  const size_t side = 2 * static_cast<size_t>(params.margin_px) + 1;
  EXPECT_GE(kept_around(320, 300), side * side - 2) << "the pair keeps its ring";

  // 0 keeps every ring.
  params.ring_min_cluster_px = 0;
  core::PointCloud again = before;
  PlanarRegionFinder(params).Compute(s.k, 0.15f, &again, &out);
  size_t kept = 0;
  for (int v = 330 - params.margin_px; v <= 330 + params.margin_px; ++v) {
    for (int u = 200 - params.margin_px; u <= 200 + params.margin_px; ++u) {
      kept += core::IsValid(again.xyz[static_cast<size_t>(v) * w + u]) ? 1 : 0;
    }
  }
  EXPECT_GE(kept, side * side - 2);
}

TEST(PlanarRegions, RegionsSmallerThanTheSupportAreaTakeNothing) {
  const int box[4] = {0, 0, 0, 0};
  Scene s = TableScene(0.001f, box, 0.f);
  const core::PointCloud before = s.cloud;
  PlanarRegionFinder finder(PlanarRegionParams{});
  PlanarRegions out;
  finder.Compute(s.k, 1000.f, &s.cloud, &out);  // no table is that large
  EXPECT_TRUE(out.regions.empty());
  EXPECT_EQ(out.num_taken_points, 0u);
  EXPECT_EQ(s.cloud.CountValid(), before.CountValid());
}

TEST(PlanarRegions, NoiseAboveTheBoundKeepsEveryPoint) {
  const int box[4] = {0, 0, 0, 0};
  Scene s = TableScene(0.06f, box, 0.f);  // 6 cm of noise: above the bound up to 3 m
  const size_t valid = s.cloud.CountValid();
  PlanarRegionFinder finder(PlanarRegionParams{});
  PlanarRegions out;
  finder.Compute(s.k, 0.15f, &s.cloud, &out);
  EXPECT_TRUE(out.regions.empty());
  EXPECT_EQ(s.cloud.CountValid(), valid);
}

// Runs the finder with its defaults and the support area of 0.15 m^2 on `s` and counts the
// regions found on the table's plane (offset within `tolerance_m`).
int TableRegions(Scene* s, float tolerance_m) {
  PlanarRegionFinder finder(PlanarRegionParams{});
  PlanarRegions out;
  finder.Compute(s->k, 0.15f, &s->cloud, &out);
  int count = 0;
  for (const PlanarRegion& r : out.regions) count += std::abs(r.d - s->d) < tolerance_m ? 1 : 0;
  return count;
}

TEST(PlanarRegions, PiecesOfOnePlaneCutApartByAnObjectAreOneRegion) {
  // A row of boxes across the whole image splits the table into a near and a far piece (the
  // row's top, parallel to the table and large, is a plane of its own).
  const int box[4] = {0, 200, 640, 260};
  Scene s = TableScene(0.001f, box, 0.1f);
  EXPECT_EQ(TableRegions(&s, 0.01f), 1);
  bool near_taken = false, far_taken = false;
  for (int v = 0; v < s.k.height; ++v) {
    const bool taken_row = !core::IsValid(s.cloud.xyz[static_cast<size_t>(v) * s.k.width + 320]);
    near_taken |= taken_row && v > 300;
    far_taken |= taken_row && v < 160;
  }
  EXPECT_TRUE(near_taken);
  EXPECT_TRUE(far_taken);
}

TEST(PlanarRegions, APieceIsJudgedAgainstThePlaneOfAllItsMergedPieces) {
  // A wall of boxes (u 480-512) cuts the table into a large piece and a strip at the right
  // whose surface is tilted by 0.02 rad about a line through its centre, as a warped or
  // badly calibrated far part of a table is. The strip's own plane, extrapolated across the
  // large piece, misses it by more than its bound, and the large piece's plane misses the
  // strip's edges by less: both lie within their bound of the plane fitted to the two.
  const int wall[4] = {480, 0, 512, 480};
  Scene s = TableScene(0.001f, wall, 0.1f);
  const float tilt = 0.02f;
  const core::CameraIntrinsics& k = s.k;
  // The strip's plane: the table's normal turned about the image's vertical through the
  // strip's centre pixel (576, 240), through that pixel's table point.
  const float ru = static_cast<float>((576 - k.cx) / k.fx),
              rv = static_cast<float>((240 - k.cy) / k.fy);
  const float zc = -s.d / (s.n.x * ru + s.n.y * rv + s.n.z);
  const core::Vec3f pc{ru * zc, rv * zc, zc};
  const core::Vec3f na{s.n.x * std::cos(tilt) + s.n.z * std::sin(tilt), s.n.y,
                       -s.n.x * std::sin(tilt) + s.n.z * std::cos(tilt)};
  const float da = -(na.x * pc.x + na.y * pc.y + na.z * pc.z);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.f, 0.001f);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 512; u < k.width; ++u) {
      const float rx = static_cast<float>((u - k.cx) / k.fx);
      const float ry = static_cast<float>((v - k.cy) / k.fy);
      const float denom = na.x * rx + na.y * ry + na.z;
      float z = denom < 0.f ? -da / denom : -1.f;
      const size_t i = static_cast<size_t>(v) * k.width + u;
      if (!(z > 0.3f && z < 3.f)) {
        s.cloud.xyz[i] = core::Vec3f{kNaN, kNaN, kNaN};
        continue;
      }
      z += noise(rng);
      s.cloud.xyz[i] = core::Vec3f{rx * z, ry * z, z};
    }
  }
  EXPECT_EQ(TableRegions(&s, 0.02f), 1);
  // Both sides of the wall are taken as that one plane's.
  bool left_taken = false, strip_taken = false;
  for (int v = 100; v < 400; ++v) {
    const size_t row = static_cast<size_t>(v) * k.width;
    left_taken |= !core::IsValid(s.cloud.xyz[row + 200]);
    strip_taken |= !core::IsValid(s.cloud.xyz[row + 576]);
  }
  EXPECT_TRUE(left_taken);
  EXPECT_TRUE(strip_taken);
}

TEST(PlanarRegions, UnorganizedOrDisabledCloudsAreLeftAsTheyAre) {
  const int box[4] = {0, 0, 0, 0};
  Scene s = TableScene(0.001f, box, 0.f);
  const size_t valid = s.cloud.CountValid();
  PlanarRegionParams off;
  off.enabled = false;
  PlanarRegions out;
  PlanarRegionFinder(off).Compute(s.k, 0.15f, &s.cloud, &out);
  EXPECT_TRUE(out.regions.empty());
  EXPECT_EQ(s.cloud.CountValid(), valid);

  core::PointCloud flat = s.cloud;
  flat.width = static_cast<int>(flat.xyz.size());
  flat.height = 1;
  PlanarRegionFinder(PlanarRegionParams{}).Compute(s.k, 0.15f, &flat, &out);
  EXPECT_TRUE(out.regions.empty());
  EXPECT_EQ(flat.CountValid(), valid);
}

TEST(PlanarRegions, ResultDoesNotDependOnThePool) {
  const int box[4] = {100, 250, 220, 330};
  const Scene s = TableScene(0.0015f, box, 0.05f, 7);
  core::PointCloud a = s.cloud, b = s.cloud;
  PlanarRegions ra, rb;
  PlanarRegionFinder(PlanarRegionParams{}).Compute(s.k, 0.15f, &a, &ra);
  core::ThreadPool pool(3);
  PlanarRegionFinder(PlanarRegionParams{}, &pool).Compute(s.k, 0.15f, &b, &rb);
  ASSERT_EQ(ra.regions.size(), rb.regions.size());
  for (size_t i = 0; i < ra.regions.size(); ++i) {
    EXPECT_EQ(ra.regions[i].d, rb.regions[i].d);
    EXPECT_EQ(ra.regions[i].num_taken_points, rb.regions[i].num_taken_points);
    EXPECT_EQ(ra.regions[i].taken_area_m2, rb.regions[i].taken_area_m2);
  }
  for (size_t i = 0; i < a.xyz.size(); ++i) {
    ASSERT_EQ(core::IsValid(a.xyz[i]), core::IsValid(b.xyz[i])) << i;
  }
}

TEST(PlanarRegions, InvalidParametersNameTheKey) {
  PlanarRegionParams p;
  p.cell_px = 2;
  testing::ExpectInvalidArgumentNaming([&] { PlanarRegionFinder finder(p); },
                                       "segmenter.support.cell_px");
}

}  // namespace
}  // namespace clutterseg::geometry
