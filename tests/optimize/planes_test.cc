#include "clutterseg/optimize/planes.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/graph/linkage.h"
#include "clutterseg/graph/patch_features.h"
#include "tests/graph/synthetic_tiles.h"

namespace clutterseg::optimize {
namespace {

namespace gt = graph::testing;

float Dot(const core::Vec3f& a, const core::Vec3f& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

double AngleDeg(const core::Vec3f& a, const core::Vec3f& b) {
  return std::acos(std::min(1.0, static_cast<double>(Dot(a, b)))) * 180.0 / 3.14159265358979;
}

struct Scene {
  gt::TabletopScene scene;
  core::PointCloud cloud;
  std::vector<int32_t> surface;
  supervoxel::Supervoxels sv;
  graph::PatchFeatures f;
  std::vector<int32_t> pure;
};

Scene MakeScene(int tile = 10, double noise_m = 0.0005) {
  Scene s;
  s.scene.depth_noise_m = noise_m;
  s.scene.boxes.push_back({{-0.1, 0.9, 0.0}, {0.1, 1.1, 0.15}});
  s.scene.boxes.push_back({{0.2, 1.2, 0.0}, {0.3, 1.3, 0.25}});
  gt::Render(s.scene, &s.cloud, &s.surface);
  s.sv = gt::TileSupervoxels(s.cloud, tile);
  graph::PatchFeatureExtractor().Compute(s.cloud, s.sv, &s.f);
  s.pure = gt::PureSurfaceOfTiles(s.sv, s.surface);
  return s;
}

// Index of the plane within `angle_deg` and `dist_m` of (n, d), or -1.
int FindMatching(const std::vector<PlaneModel>& planes, const core::Vec3f& n, float d,
                 double angle_deg, double dist_m) {
  for (size_t p = 0; p < planes.size(); ++p) {
    if (AngleDeg(planes[p].normal, n) < angle_deg && std::fabs(planes[p].d - d) < dist_m) {
      return static_cast<int>(p);
    }
  }
  return -1;
}

TEST(PlaneLabeler, FindsTableAndWallWithAccurateRefit) {
  const Scene s = MakeScene();
  PlaneLabeler dut(PlaneParams{});
  std::vector<PlaneModel> planes;
  dut.FindPlanes(s.f, &planes);
  core::Vec3f table_n, wall_n;
  float table_d, wall_d;
  gt::TablePlane(s.scene, &table_n, &table_d);
  gt::WallPlane(s.scene, &wall_n, &wall_d);
  ASSERT_EQ(planes.size(), 2u);  // the boxes' faces are below kappa = 50 patches
  const int table = FindMatching(planes, table_n, table_d, 0.5, 0.001);
  const int wall = FindMatching(planes, wall_n, wall_d, 0.5, 0.001);
  ASSERT_GE(table, 0) << "table not found within 0.5 deg / 1 mm";
  ASSERT_GE(wall, 0) << "wall not found within 0.5 deg / 1 mm";
  for (const PlaneModel& p : planes) {
    EXPECT_NEAR(std::sqrt(Dot(p.normal, p.normal)), 1.0, 1e-5);
    EXPECT_GT(p.d, 0.f);  // normal towards the camera
    EXPECT_GE(p.num_patches, 50u);
  }
}

TEST(PlaneLabeler, LabelsTableAndWallButNotTheBoxes) {
  const Scene s = MakeScene();
  PlaneLabeler dut(PlaneParams{});
  PlaneLabeling out;
  dut.Compute(s.sv, s.f, &out);
  ASSERT_EQ(out.patch_plane.size(), s.sv.size());
  core::Vec3f table_n, wall_n;
  float table_d, wall_d;
  gt::TablePlane(s.scene, &table_n, &table_d);
  gt::WallPlane(s.scene, &wall_n, &wall_d);
  const int table = FindMatching(out.planes, table_n, table_d, 0.5, 0.001);
  const int wall = FindMatching(out.planes, wall_n, wall_d, 0.5, 0.001);
  ASSERT_GE(table, 0);
  ASSERT_GE(wall, 0);
  int table_tiles = 0, table_ok = 0, wall_tiles = 0, wall_ok = 0, box_tiles = 0;
  uint32_t table_points = 0;
  for (size_t i = 0; i < s.sv.size(); ++i) {
    if (out.patch_plane[i] == table) table_points += s.f.num_points[i];
    if (s.pure[i] == gt::kSurfaceTable) {
      ++table_tiles;
      table_ok += out.patch_plane[i] == table ? 1 : 0;
    } else if (s.pure[i] == gt::kSurfaceWall) {
      ++wall_tiles;
      wall_ok += out.patch_plane[i] == wall ? 1 : 0;
    } else if (s.pure[i] >= gt::kSurfaceBox0) {
      ++box_tiles;
      EXPECT_NE(out.patch_plane[i], table) << "box tile " << i;
      EXPECT_NE(out.patch_plane[i], wall) << "box tile " << i;
    }
  }
  EXPECT_GT(box_tiles, 40);
  EXPECT_GT(table_ok, 0.98 * table_tiles);
  EXPECT_GT(wall_ok, 0.98 * wall_tiles);
  EXPECT_EQ(out.planes[table].num_points, table_points);
  EXPECT_GE(out.expansion_cycles, 1);
}

TEST(PlaneLabeler, AFoundPlaneAlongAFixedOneTakesItsFitWhenTheyDisagree) {
  // The fixed plane (found on the pixel grid before the supervoxels) is the table turned by
  // 2 degrees and moved by 5 mm: within duplicate_angle_deg / duplicate_distance_m of the
  // plane found on the supervoxels, so the two are one hypothesis, with the fixed plane's
  // points and area, and, 2 degrees being more than fixed_fit_max_angle_deg, its fit.
  const Scene s = MakeScene();
  core::Vec3f table_n;
  float table_d;
  gt::TablePlane(s.scene, &table_n, &table_d);
  const double a = 2.0 * 3.14159265358979 / 180.0;
  PlaneModel fixed;
  fixed.normal =
      core::Vec3f{table_n.x, static_cast<float>(std::cos(a) * table_n.y - std::sin(a) * table_n.z),
                  static_cast<float>(std::sin(a) * table_n.y + std::cos(a) * table_n.z)};
  fixed.d = table_d + 0.005f;
  fixed.fixed_points = 1000;
  fixed.fixed_area_m2 = 0.5f;
  ASSERT_NEAR(AngleDeg(fixed.normal, table_n), 2.0, 0.01);
  PlaneLabeler dut(PlaneParams{});
  PlaneLabeling out;
  dut.Compute(s.sv, s.f, {fixed}, &out);
  int holders = 0;
  for (const PlaneModel& p : out.planes) {
    if (p.fixed_points == 0) {
      // No other plane along the table is left.
      EXPECT_FALSE(AngleDeg(p.normal, table_n) < 5.0 && std::fabs(p.d - table_d) < 0.02f);
      continue;
    }
    ++holders;
    EXPECT_EQ(p.fixed_points, 1000u);
    EXPECT_FLOAT_EQ(p.fixed_area_m2, 0.5f);
    EXPECT_FLOAT_EQ(p.normal.y, fixed.normal.y);
    EXPECT_FLOAT_EQ(p.normal.z, fixed.normal.z);
    EXPECT_FLOAT_EQ(p.d, fixed.d);
    EXPECT_GT(p.num_patches, 0u);  // the found plane's supervoxels, not a hypothesis of its own
  }
  EXPECT_EQ(holders, 1);
  // Allowed to differ by up to 5 degrees, the found plane keeps its own fit (the table).
  PlaneParams keep;
  keep.fixed_fit_max_angle_deg = 5.f;
  PlaneLabeler(keep).Compute(s.sv, s.f, {fixed}, &out);
  holders = 0;
  for (const PlaneModel& p : out.planes) {
    if (p.fixed_points == 0) continue;
    ++holders;
    EXPECT_LT(AngleDeg(p.normal, table_n), 0.5);
    EXPECT_NEAR(p.d, table_d, 0.001f);
  }
  EXPECT_EQ(holders, 1);
}

TEST(PlaneLabeler, NoPlaneWhenTooFewPatches) {
  const Scene s = MakeScene();
  PlaneParams p;
  p.min_inlier_patches = 100000;
  PlaneLabeler dut(p);
  PlaneLabeling out;
  dut.Compute(s.sv, s.f, &out);
  EXPECT_TRUE(out.planes.empty());
  EXPECT_EQ(out.num_hypotheses, 0);
  for (int32_t l : out.patch_plane) EXPECT_EQ(l, -1);
}

TEST(PlaneLabeler, FeatureTermPushesNonPlanarPatchesToNoPlane) {
  // A patch on the table plane but scattered (a2D = 0) and isolated from the graph:
  // D(table) + F(table) = 0 + kf, D(l0) + F(l0) = 2; with kf > 2 it prefers l0.
  Scene s = MakeScene();
  size_t probe = 0;
  for (size_t i = 0; i < s.sv.size(); ++i) {
    if (s.pure[i] == gt::kSurfaceTable && s.f.num_points[i] == 100) {
      probe = i;
      break;
    }
  }
  s.f.a2d[probe] = 0.f;
  PlaneParams p;
  p.smoothness_weight = 0.f;
  p.feature_weight = 3.f;
  PlaneLabeling out;
  PlaneLabeler(p).Compute(s.sv, s.f, &out);
  EXPECT_EQ(out.patch_plane[probe], -1);
  p.feature_weight = 1.f;
  PlaneLabeler(p).Compute(s.sv, s.f, &out);
  EXPECT_GE(out.patch_plane[probe], 0);
}

TEST(PlaneLabeler, ValidatesParamsAndSizes) {
  PlaneParams bad;
  bad.inlier_distance_m = 0.f;
  EXPECT_THROW(PlaneLabeler{bad}, std::invalid_argument);
  bad = PlaneParams{};
  bad.min_inlier_patches = 0;
  EXPECT_THROW(PlaneLabeler{bad}, std::invalid_argument);
  bad = PlaneParams{};
  bad.inlier_angle_deg = 120.f;
  try {
    PlaneLabeler{bad};
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("inlier_angle_deg"), std::string::npos) << e.what();
  }
  const Scene s = MakeScene(16);
  graph::PatchFeatures f = s.f;
  f.Resize(3);
  PlaneLabeling out;
  EXPECT_THROW(PlaneLabeler(PlaneParams{}).Compute(s.sv, f, &out), std::runtime_error);
}

TEST(PlaneLabeler, DeterministicAcrossRuns) {
  const Scene s = MakeScene();
  PlaneLabeler dut(PlaneParams{});
  PlaneLabeling a, b;
  dut.Compute(s.sv, s.f, &a);
  dut.Compute(s.sv, s.f, &b);
  EXPECT_EQ(a.patch_plane, b.patch_plane);
  EXPECT_EQ(a.energy, b.energy);
}

// Times the graph and optimisation stages on a full 640x480 frame cut into 10x10 tiles
// (about 3000 supervoxels), without and with a 2-thread pool; prints the numbers (best of 10
// wall-clock runs) and asserts nothing about time.
TEST(PlaneLabeler, ReportsStageTimesOnRealisticSize) {
  const Scene s = MakeScene(10, 0.001);
  for (int threads : {0, 2}) {
    std::unique_ptr<core::ThreadPool> pool;
    if (threads > 0) pool = std::make_unique<core::ThreadPool>(threads);
    graph::PatchFeatureExtractor features(pool.get());
    graph::Linkage linkage(graph::LinkageParams{}, pool.get());
    PlaneLabeler planes(PlaneParams{});
    graph::PatchFeatures f;
    graph::LinkageResult link;
    PlaneLabeling out;
    using Clock = std::chrono::steady_clock;
    double best[3] = {1e9, 1e9, 1e9};
    for (int rep = 0; rep < 10; ++rep) {
      const auto t0 = Clock::now();
      features.Compute(s.cloud, s.sv, &f);
      const auto t1 = Clock::now();
      linkage.Compute(s.sv, f, &link);
      const auto t2 = Clock::now();
      planes.Compute(s.sv, f, &out);
      const auto t3 = Clock::now();
      const double ms[3] = {std::chrono::duration<double, std::milli>(t1 - t0).count(),
                            std::chrono::duration<double, std::milli>(t2 - t1).count(),
                            std::chrono::duration<double, std::milli>(t3 - t2).count()};
      for (int k = 0; k < 3; ++k) best[k] = std::min(best[k], ms[k]);
    }
    std::printf(
        "[ timing ] %zu supervoxels, %zu edges, pool %d: features %.3f ms, linkage %.3f "
        "ms, planes+expansion %.3f ms (%d planes, %d cycles, %d segments)\n",
        s.sv.size(), s.sv.num_edges(), threads, best[0], best[1], best[2],
        static_cast<int>(out.planes.size()), out.expansion_cycles, link.num_segments);
    EXPECT_EQ(out.patch_plane.size(), s.sv.size());
  }
}

}  // namespace
}  // namespace clutterseg::optimize
