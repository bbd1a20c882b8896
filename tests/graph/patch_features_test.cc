#include "clutterseg/graph/patch_features.h"

#include <cmath>
#include <cstring>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/supervoxel/supervoxelizer.h"
#include "tests/graph/synthetic_tiles.h"

namespace clutterseg::graph {
namespace {

// An organized cloud of `n` x 1 pixels... kept 2-D (n x 2) so that it is organized.
struct SinglePatch {
  core::PointCloud cloud;
  supervoxel::Supervoxels sv;
};

SinglePatch MakeSinglePatch(const std::vector<core::Vec3f>& points) {
  SinglePatch s;
  const int w = static_cast<int>(points.size());
  s.cloud.width = w;
  s.cloud.height = 2;
  s.cloud.xyz = points;
  s.cloud.xyz.resize(2 * points.size(), core::Vec3f{core::kInvalidDepth, 0.f, 0.f});
  s.sv.width = w;
  s.sv.height = 2;
  s.sv.pixel_label.assign(2 * points.size(), 0);
  s.sv.centroid.resize(1);
  s.sv.normal.resize(1);
  s.sv.curvature.resize(1);
  s.sv.num_points.assign(1, static_cast<uint32_t>(points.size()));
  s.sv.adjacency_offsets = {0, 0};
  return s;
}

float Dot(const core::Vec3f& a, const core::Vec3f& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

TEST(PatchFeatures, PlanePatchIsPlanarWithCameraFacingNormal) {
  // Plane z = 1 + 0.3 x - 0.2 y, sampled on a grid with a little noise.
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.f, 1e-4f);
  std::vector<core::Vec3f> pts;
  for (int i = 0; i < 15; ++i) {
    for (int j = 0; j < 15; ++j) {
      const float x = -0.02f + 0.003f * i, y = 0.1f + 0.003f * j;
      pts.push_back({x, y, 1.f + 0.3f * x - 0.2f * y + noise(rng)});
    }
  }
  SinglePatch s = MakeSinglePatch(pts);
  PatchFeatures f;
  PatchFeatureExtractor dut;
  dut.Compute(s.cloud, s.sv, &f);
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f.num_points[0], pts.size());
  EXPECT_EQ(f.type[0], PatchType::kPlanar);
  EXPECT_GT(f.a2d[0], 0.75f);
  EXPECT_GT(f.a2d[0], f.a1d[0]);
  EXPECT_GT(f.a2d[0], f.a3d[0]);
  EXPECT_NEAR(f.a1d[0] + f.a2d[0] + f.a3d[0], 1.f, 1e-5f);
  EXPECT_LT(f.curvature[0], 1e-3f);
  // True normal of z - 0.3x + 0.2y = 1 is (-0.3, 0.2, 1) normalised; towards the camera it
  // has negative z.
  const float len = std::sqrt(0.09f + 0.04f + 1.f);
  const core::Vec3f expected{0.3f / len, -0.2f / len, -1.f / len};
  EXPECT_GT(Dot(f.normal[0], expected), std::cos(0.5f * 3.14159265f / 180.f));
  EXPECT_LT(Dot(f.normal[0], f.centroid[0]), 0.f);
  const float l1 = f.eigenvalues[0].x, l2 = f.eigenvalues[0].y, l3 = f.eigenvalues[0].z;
  EXPECT_GE(l1, l2);
  EXPECT_GE(l2, l3);
}

TEST(PatchFeatures, LineIsLinear) {
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.f, 2e-4f);
  std::vector<core::Vec3f> pts;
  for (int i = 0; i < 60; ++i) {
    const float t = 0.001f * i;
    pts.push_back({0.1f + t + noise(rng), -0.05f + 0.5f * t + noise(rng), 0.9f + noise(rng)});
  }
  SinglePatch s = MakeSinglePatch(pts);
  PatchFeatures f;
  PatchFeatureExtractor().Compute(s.cloud, s.sv, &f);
  EXPECT_EQ(f.type[0], PatchType::kNonPlanar);
  EXPECT_GT(f.a1d[0], 0.7f);
  EXPECT_GT(f.a1d[0], f.a2d[0]);
  EXPECT_GT(f.a1d[0], f.a3d[0]);
}

TEST(PatchFeatures, RandomBlobIsScattered) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.01f, 0.01f);
  std::vector<core::Vec3f> pts;
  for (int i = 0; i < 400; ++i) pts.push_back({u(rng), 0.2f + u(rng), 1.2f + u(rng)});
  SinglePatch s = MakeSinglePatch(pts);
  PatchFeatures f;
  PatchFeatureExtractor().Compute(s.cloud, s.sv, &f);
  EXPECT_EQ(f.type[0], PatchType::kNonPlanar);
  EXPECT_GT(f.a3d[0], 0.7f);
  EXPECT_GT(f.a3d[0], f.a1d[0]);
  EXPECT_GT(f.a3d[0], f.a2d[0]);
  EXPECT_GT(f.curvature[0], 0.2f);
}

TEST(PatchFeatures, IgnoresInvalidPointsAndUnlabelledPixels) {
  std::vector<core::Vec3f> pts = {{0, 0, 1}, {0.01f, 0, 1}, {0, 0.01f, 1}, {0.01f, 0.01f, 1}};
  SinglePatch s = MakeSinglePatch(pts);
  // Second row: invalid points labelled 0 and one valid far point with label -1.
  s.cloud.xyz[4] = core::Vec3f{5.f, 5.f, 5.f};
  s.sv.pixel_label[4] = -1;
  PatchFeatures f;
  PatchFeatureExtractor().Compute(s.cloud, s.sv, &f);
  EXPECT_EQ(f.num_points[0], 4u);
  EXPECT_NEAR(f.centroid[0].x, 0.005f, 1e-6f);
  EXPECT_NEAR(f.centroid[0].y, 0.005f, 1e-6f);
  EXPECT_NEAR(f.centroid[0].z, 1.f, 1e-6f);
  EXPECT_NEAR(f.normal[0].z, -1.f, 1e-5f);
}

TEST(PatchFeatures, EmptySupervoxelIsDegenerate) {
  std::vector<core::Vec3f> pts = {{0, 0, 1}, {0.01f, 0, 1}, {0, 0.01f, 1}};
  SinglePatch s = MakeSinglePatch(pts);
  s.sv.centroid.resize(2);
  s.sv.normal.resize(2);
  s.sv.curvature.resize(2);
  s.sv.num_points.resize(2);
  s.sv.adjacency_offsets = {0, 0, 0};
  PatchFeatures f;
  PatchFeatureExtractor().Compute(s.cloud, s.sv, &f);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f.num_points[1], 0u);
  EXPECT_EQ(f.type[1], PatchType::kNonPlanar);
  EXPECT_EQ(f.a2d[1], 0.f);
}

TEST(PatchFeatures, ThrowsOnMismatchedSizesAndBadLabels) {
  std::vector<core::Vec3f> pts = {{0, 0, 1}, {0.01f, 0, 1}, {0, 0.01f, 1}};
  SinglePatch s = MakeSinglePatch(pts);
  PatchFeatures f;
  PatchFeatureExtractor dut;
  core::PointCloud wrong = s.cloud;
  wrong.width = 2;
  EXPECT_THROW(dut.Compute(wrong, s.sv, &f), std::runtime_error);
  s.sv.pixel_label[1] = 7;
  EXPECT_THROW(dut.Compute(s.cloud, s.sv, &f), std::runtime_error);
}

TEST(PatchFeatures, MatchesDirectComputationOnScene) {
  testing::TabletopScene scene;
  scene.width = 320;
  scene.height = 240;
  scene.fx = scene.fy = 262.5;
  scene.cx = 159.5;
  scene.cy = 119.5;
  scene.boxes.push_back({{-0.1, 0.9, 0.0}, {0.1, 1.1, 0.15}});
  core::PointCloud cloud;
  std::vector<int32_t> surface;
  testing::Render(scene, &cloud, &surface);
  const supervoxel::Supervoxels sv = testing::TileSupervoxels(cloud, 10);
  PatchFeatures f;
  PatchFeatureExtractor().Compute(cloud, sv, &f);
  ASSERT_EQ(f.size(), sv.size());
  // Two-pass reference in double.
  const size_t n = sv.size();
  std::vector<double> cnt(n, 0), mx(n, 0), my(n, 0), mz(n, 0);
  for (size_t p = 0; p < cloud.xyz.size(); ++p) {
    const int32_t id = sv.pixel_label[p];
    if (id < 0) continue;
    cnt[id] += 1;
    mx[id] += cloud.xyz[p].x;
    my[id] += cloud.xyz[p].y;
    mz[id] += cloud.xyz[p].z;
  }
  std::vector<double> czz(n, 0), cxy(n, 0);
  for (size_t p = 0; p < cloud.xyz.size(); ++p) {
    const int32_t id = sv.pixel_label[p];
    if (id < 0) continue;
    const double dx = cloud.xyz[p].x - mx[id] / cnt[id];
    const double dy = cloud.xyz[p].y - my[id] / cnt[id];
    const double dz = cloud.xyz[p].z - mz[id] / cnt[id];
    czz[id] += dz * dz;
    cxy[id] += dx * dy;
  }
  for (size_t i = 0; i < n; ++i) {
    ASSERT_EQ(f.num_points[i], static_cast<uint32_t>(cnt[i]));
    EXPECT_NEAR(f.centroid[i].x, mx[i] / cnt[i], 1e-6);
    EXPECT_NEAR(f.centroid[i].z, mz[i] / cnt[i], 1e-6);
    EXPECT_NEAR(f.covariance[i][5], czz[i] / cnt[i], 1e-8);
    EXPECT_NEAR(f.covariance[i][1], cxy[i] / cnt[i], 1e-8);
    // Normals face the camera.
    EXPECT_LE(Dot(f.normal[i], f.centroid[i]), 0.f);
  }
  // Image tiles on the table are foreshortened (elongated in 3-D), so check their normals
  // only; roughly isotropic 3-D cells of the table must also be planar.
  core::Vec3f table_n;
  float table_d;
  testing::TablePlane(scene, &table_n, &table_d);
  const float cos10 = std::cos(10.f * 3.14159265f / 180.f);
  const std::vector<int32_t> pure = testing::PureSurfaceOfTiles(sv, surface);
  int table_tiles = 0;
  for (size_t i = 0; i < n; ++i) {
    if (pure[i] != testing::kSurfaceTable || f.num_points[i] < 50) continue;
    ++table_tiles;
    EXPECT_GT(Dot(f.normal[i], table_n), cos10) << "tile " << i;
  }
  EXPECT_GT(table_tiles, 100);

  const supervoxel::Supervoxels cells = testing::VoxelSupervoxels(scene, cloud, 0.03);
  PatchFeatures fc;
  PatchFeatureExtractor().Compute(cloud, cells, &fc);
  const std::vector<int32_t> pure_cells = testing::PureSurfaceOfTiles(cells, surface);
  int table_cells = 0;
  for (size_t i = 0; i < cells.size(); ++i) {
    if (pure_cells[i] != testing::kSurfaceTable || fc.num_points[i] < 30) continue;
    ++table_cells;
    EXPECT_EQ(fc.type[i], PatchType::kPlanar) << "cell " << i;
    EXPECT_GT(fc.a2d[i], fc.a1d[i]) << "cell " << i;
    EXPECT_GT(Dot(fc.normal[i], table_n), cos10) << "cell " << i;
  }
  EXPECT_GT(table_cells, 100);
}

TEST(PatchFeatures, IdenticalForAnyThreadCount) {
  testing::TabletopScene scene;
  scene.boxes.push_back({{-0.1, 0.9, 0.0}, {0.1, 1.1, 0.15}});
  core::PointCloud cloud;
  std::vector<int32_t> surface;
  testing::Render(scene, &cloud, &surface);
  const supervoxel::Supervoxels sv = testing::TileSupervoxels(cloud, 12);
  PatchFeatures reference;
  PatchFeatureExtractor().Compute(cloud, sv, &reference);
  for (int threads : {1, 2, 3}) {
    core::ThreadPool pool(threads);
    PatchFeatureExtractor dut(&pool);
    PatchFeatures f;
    dut.Compute(cloud, sv, &f);
    dut.Compute(cloud, sv, &f);  // buffers reused
    ASSERT_EQ(f.size(), reference.size());
    EXPECT_EQ(0, std::memcmp(f.centroid.data(), reference.centroid.data(),
                             f.size() * sizeof(core::Vec3f)));
    EXPECT_EQ(
        0, std::memcmp(f.normal.data(), reference.normal.data(), f.size() * sizeof(core::Vec3f)));
    EXPECT_EQ(0, std::memcmp(f.a2d.data(), reference.a2d.data(), f.size() * sizeof(float)));
    EXPECT_EQ(f.type, reference.type);
  }
}

TEST(PatchFeatures, SupervoxelMomentsGiveThePixelResult) {
  // The supervoxelizer hands over its members' moments; features computed from them must
  // equal those accumulated from the pixels (up to the order of summation).
  testing::TabletopScene scene;
  scene.boxes.push_back({{-0.1, 0.9, 0.0}, {0.1, 1.1, 0.15}});
  scene.boxes.push_back({{0.12, 0.95, 0.0}, {0.2, 1.05, 0.3}});
  core::PointCloud cloud;
  std::vector<int32_t> surface;
  testing::Render(scene, &cloud, &surface);
  supervoxel::Supervoxelizer svz{supervoxel::SupervoxelParams{}};
  supervoxel::Supervoxels sv;
  svz.Compute(cloud, &sv);
  ASSERT_GT(sv.size(), 100u);
  ASSERT_EQ(sv.moments.size(), 10 * sv.size());
  PatchFeatures from_moments;
  PatchFeatureExtractor().Compute(cloud, sv, &from_moments);
  sv.moments.clear();
  PatchFeatures from_pixels;
  PatchFeatureExtractor().Compute(cloud, sv, &from_pixels);
  ASSERT_EQ(from_moments.size(), from_pixels.size());
  int planar = 0;
  for (size_t i = 0; i < sv.size(); ++i) {
    ASSERT_EQ(from_moments.num_points[i], from_pixels.num_points[i]) << "supervoxel " << i;
    ASSERT_GT(from_pixels.num_points[i], 0u);
    EXPECT_NEAR(from_moments.centroid[i].z, from_pixels.centroid[i].z, 1e-6);
    EXPECT_NEAR(from_moments.covariance[i][5], from_pixels.covariance[i][5], 1e-9);
    EXPECT_NEAR(from_moments.curvature[i], from_pixels.curvature[i], 1e-4);
    if (from_pixels.num_points[i] >= 30) {
      EXPECT_GT(std::fabs(Dot(from_moments.normal[i], from_pixels.normal[i])), 0.9999f);
    }
    planar += from_pixels.type[i] == PatchType::kPlanar;
  }
  EXPECT_GT(planar, static_cast<int>(sv.size()) / 2);
}

}  // namespace
}  // namespace clutterseg::graph
