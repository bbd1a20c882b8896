#include "clutterseg/geometry/voxel_grid.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/geometry/moments.h"

namespace clutterseg::geometry {
namespace {

constexpr float kNaN = core::kInvalidDepth;

VoxelGridParams Euclidean(float res) {
  VoxelGridParams p;
  p.voxel_resolution_m = res;
  p.use_single_camera_transform = false;
  return p;
}

VoxelGridParams CameraSpace(float res) {
  VoxelGridParams p;
  p.voxel_resolution_m = res;
  p.use_single_camera_transform = true;
  return p;
}

// Unorganized random cloud: clustered so that many voxels have neighbours, plus NaNs.
core::PointCloud RandomCloud(uint32_t seed, size_t n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> centre(-0.3f, 0.3f);
  std::normal_distribution<float> spread(0.f, 0.02f);
  std::uniform_int_distribution<int> nan_pick(0, 19);
  core::PointCloud cloud;
  cloud.width = static_cast<int>(n);
  cloud.height = 1;
  cloud.xyz.resize(n);
  core::Vec3f c{};
  for (size_t i = 0; i < n; ++i) {
    if (i % 50 == 0) c = {centre(rng), centre(rng), 1.0f + centre(rng)};
    cloud.xyz[i] = {c.x + spread(rng), c.y + spread(rng), c.z + spread(rng)};
    if (nan_pick(rng) == 0) cloud.xyz[i].y = kNaN;
  }
  return cloud;
}

// An organized cloud of a plane n.p = d seen by a Kinect camera (exact floats), 0.4-1.6 m:
// farther, a Euclidean 7.5 mm grid on a slanted plane starts to fall apart into sparse voxels.
core::PointCloud PlaneCloud(const core::Vec3f& n, float d) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  core::PointCloud cloud;
  cloud.width = k.width;
  cloud.height = k.height;
  cloud.xyz.resize(static_cast<size_t>(k.width) * k.height);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const float rx = static_cast<float>((u - k.cx) / k.fx);
      const float ry = static_cast<float>((v - k.cy) / k.fy);
      const float t = d / (n.x * rx + n.y * ry + n.z);
      core::Vec3f& p = cloud.xyz[static_cast<size_t>(v) * k.width + u];
      p = (t > 0.4f && t < 1.6f) ? core::Vec3f{rx * t, ry * t, t} : core::Vec3f{kNaN, kNaN, kNaN};
    }
  }
  return cloud;
}

TEST(VoxelGridParams, ValidateRejectsBadValuesNamingTheKey) {
  EXPECT_NO_THROW(VoxelGridParams{}.ValidateOrThrow());
  VoxelGridParams p;
  p.voxel_resolution_m = 0.f;
  try {
    p.ValidateOrThrow();
    FAIL() << "expected a throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("voxel_resolution_m"), std::string::npos);
  }
  p = {};
  p.voxel_resolution_m = std::nanf("");
  EXPECT_THROW(p.ValidateOrThrow(), std::invalid_argument);
  EXPECT_THROW(Voxelizer{p}, std::invalid_argument);
}

TEST(VoxelGrid, KeysCountsAndCentroidsOfAHandMadeCloud) {
  // 2x3 organized cloud at 1 cm resolution: three points in voxel (0, 0, 100), two in
  // (1, 0, 100), one NaN.
  core::PointCloud cloud;
  cloud.width = 3;
  cloud.height = 2;
  cloud.xyz = {{0.001f, 0.002f, 1.001f}, {0.003f, 0.004f, 1.003f}, {0.015f, 0.001f, 1.005f},
               {0.005f, 0.009f, 1.008f}, {kNaN, kNaN, kNaN},       {0.019f, 0.003f, 1.002f}};
  cloud.rgba = {core::PackRgba({10, 20, 30}), core::PackRgba({30, 40, 50}),
                core::PackRgba({0, 0, 0}),    core::PackRgba({20, 30, 40}),
                core::PackRgba({0, 0, 0}),    core::PackRgba({100, 100, 100})};
  Voxelizer dut(Euclidean(0.01f));
  VoxelGrid grid;
  dut.Compute(cloud, true, &grid);
  ASSERT_EQ(grid.size(), 2u);
  // Key order is (x, y, z): (0, 0, 100) before (1, 0, 100).
  EXPECT_EQ(grid.coord[0].x, 0);
  EXPECT_EQ(grid.coord[0].y, 0);
  EXPECT_EQ(grid.coord[0].z, 100);
  EXPECT_EQ(grid.coord[1].x, 1);
  EXPECT_EQ(grid.coord[1].z, 100);
  EXPECT_LT(grid.key[0], grid.key[1]);
  EXPECT_EQ(grid.key[0], PackVoxelKey(grid.coord[0]));
  EXPECT_EQ(grid.point_voxel, (std::vector<int32_t>{0, 0, 1, 0, -1, 1}));
  EXPECT_EQ(grid.num_points, (std::vector<uint32_t>{3, 2}));
  EXPECT_NEAR(grid.centroid[0].x, 0.003f, 1e-6f);
  EXPECT_NEAR(grid.centroid[0].y, 0.005f, 1e-6f);
  EXPECT_NEAR(grid.centroid[0].z, 1.004f, 1e-6f);
  EXPECT_NEAR(grid.centroid[1].x, 0.017f, 1e-6f);
  EXPECT_NEAR(grid.centroid[1].z, 1.0035f, 1e-6f);
  ASSERT_EQ(grid.mean_color.size(), 2u);
  EXPECT_FLOAT_EQ(grid.mean_color[0].x, 20.f);
  EXPECT_FLOAT_EQ(grid.mean_color[0].z, 40.f);
  EXPECT_FLOAT_EQ(grid.mean_color[1].y, 50.f);
  EXPECT_NEAR(grid.point_sums[9 * 1 + 3], 0.015 * 0.015 + 0.019 * 0.019, 1e-9);
  EXPECT_EQ(grid.adjacency_offsets, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(grid.adjacency, (std::vector<uint32_t>{1, 0}));
  EXPECT_EQ(grid.FindVoxel({1, 0, 100}), 1);
  EXPECT_EQ(grid.FindVoxel({2, 0, 100}), -1);
  // Two voxels: too few for a plane, so the normal points at the camera.
  EXPECT_FLOAT_EQ(grid.curvature[0], 1.f / 3.f);
  EXPECT_LT(grid.normal[0].z, -0.99f);
}

TEST(VoxelGrid, NegativeCoordinatesFloorAndTheCameraTransformScalesWithDepth) {
  Voxelizer euclid(Euclidean(0.01f));
  VoxelCoord c;
  ASSERT_TRUE(euclid.Quantize({-0.001f, -0.015f, 0.5f}, &c));
  EXPECT_EQ(c.x, -1);
  EXPECT_EQ(c.y, -2);
  EXPECT_EQ(c.z, 50);
  EXPECT_FALSE(euclid.Quantize({kNaN, 0.f, 1.f}, &c));
  EXPECT_FLOAT_EQ(euclid.VoxelSizeAt(3.f), 0.01f);

  Voxelizer camera(CameraSpace(0.01f));
  ASSERT_TRUE(camera.Quantize({0.105f, -0.205f, 2.0f}, &c));
  EXPECT_EQ(c.x, 5);    // 0.105 / 2 / 0.01 = 5.25
  EXPECT_EQ(c.y, -11);  // -0.205 / 2 / 0.01 = -10.25
  EXPECT_EQ(c.z, static_cast<int>(std::floor(std::log(2.0) / 0.01)));
  EXPECT_FALSE(camera.Quantize({0.f, 0.f, -1.f}, &c));
  EXPECT_FLOAT_EQ(camera.VoxelSizeAt(2.f), 0.02f);
  // At depth z a voxel spans res * z in x: points 1.5 cm apart at 2 m share a voxel.
  VoxelCoord a, b;
  ASSERT_TRUE(camera.Quantize({0.001f, 0.001f, 2.0f}, &a));
  ASSERT_TRUE(camera.Quantize({0.016f, 0.001f, 2.0f}, &b));
  EXPECT_EQ(a.x, b.x);
}

// The camera transform's quantisation (its own vectorised logarithm) against a double
// precision reference, over the depths a sensor delivers and beyond; a point may land on
// either side only within float rounding of a cell boundary.
TEST(VoxelGrid, CameraQuantisationMatchesADoublePrecisionReference) {
  const double res = 0.0075;
  Voxelizer camera(CameraSpace(static_cast<float>(res)));
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> depth(0.05f, 40.f), slope(-0.7f, 0.7f);
  int checked = 0;
  for (int k = 0; k < 200000; ++k) {
    const float z = depth(rng);
    const core::Vec3f p{slope(rng) * z, slope(rng) * z, z};
    VoxelCoord c;
    ASSERT_TRUE(camera.Quantize(p, &c));
    const double q[3] = {static_cast<double>(p.x) / p.z / res, static_cast<double>(p.y) / p.z / res,
                         std::log(static_cast<double>(p.z)) / res};
    const int32_t got[3] = {c.x, c.y, c.z};
    for (int d = 0; d < 3; ++d) {
      const double f = std::floor(q[d]);
      if (q[d] - f < 1e-4 || f + 1 - q[d] < 1e-4) continue;  // within rounding of a boundary
      EXPECT_EQ(got[d], static_cast<int32_t>(f))
          << "axis " << d << " of (" << p.x << ", " << p.y << ", " << p.z << ")";
      ++checked;
    }
  }
  EXPECT_GT(checked, 590000);
}

TEST(VoxelGrid, AdjacencyEqualsBruteForce26Neighbourhood) {
  // Seed 4 adds a solid 10 cm block: columns of about ten voxels, so that the voxelizer's path
  // for neighbourhoods of tall columns is certainly taken, beside the one for short columns.
  for (uint32_t seed : {1u, 2u, 3u, 4u}) {
    for (bool camera : {false, true}) {
      core::PointCloud cloud = RandomCloud(seed, 4000);
      if (seed == 4) {
        for (int i = 0; i < 20; ++i) {
          for (int j = 0; j < 20; ++j) {
            for (int k = 0; k < 20; ++k) {
              cloud.xyz.push_back({0.4f + 0.005f * i, 0.4f + 0.005f * j, 1.2f + 0.005f * k});
            }
          }
        }
        cloud.width = static_cast<int>(cloud.xyz.size());
      }
      Voxelizer dut(camera ? CameraSpace(0.01f) : Euclidean(0.01f));
      VoxelGrid grid;
      dut.Compute(cloud, true, &grid);
      const size_t n = grid.size();
      ASSERT_GT(n, 500u);
      ASSERT_EQ(grid.adjacency_offsets.size(), n + 1);
      // Every valid point is in the voxel its coordinates quantise to.
      for (size_t i = 0; i < cloud.size(); ++i) {
        VoxelCoord c;
        if (!dut.Quantize(cloud.xyz[i], &c)) {
          EXPECT_EQ(grid.point_voxel[i], -1);
          continue;
        }
        ASSERT_GE(grid.point_voxel[i], 0);
        const VoxelCoord& g = grid.coord[static_cast<size_t>(grid.point_voxel[i])];
        EXPECT_EQ(std::tie(c.x, c.y, c.z), std::tie(g.x, g.y, g.z));
      }
      size_t edges = 0;
      for (size_t a = 0; a < n; ++a) {
        if (a > 0) {
          ASSERT_LT(grid.key[a - 1], grid.key[a]);
        }
        std::vector<uint32_t> expected;
        for (size_t b = 0; b < n; ++b) {
          const VoxelCoord& p = grid.coord[a];
          const VoxelCoord& q = grid.coord[b];
          if (a != b && std::abs(p.x - q.x) <= 1 && std::abs(p.y - q.y) <= 1 &&
              std::abs(p.z - q.z) <= 1) {
            expected.push_back(static_cast<uint32_t>(b));
          }
        }
        const std::vector<uint32_t> got(grid.adjacency.begin() + grid.adjacency_offsets[a],
                                        grid.adjacency.begin() + grid.adjacency_offsets[a + 1]);
        ASSERT_EQ(got, expected) << "voxel " << a << " seed " << seed << " camera " << camera;
        edges += got.size();
      }
      EXPECT_GT(edges, n);  // the clusters make a connected-ish graph, not isolated voxels
    }
  }
}

TEST(VoxelGrid, PlaneNormalsPointToTheCameraAndMatchThePlane) {
  const std::vector<core::Vec3f> normals = {
      {0.f, 0.f, -1.f}, {0.f, -0.7071f, -0.7071f}, {0.5f, 0.3f, -0.8124f}};
  for (bool camera : {false, true}) {
    for (const core::Vec3f& n : normals) {
      const core::PointCloud cloud = PlaneCloud(n, -1.0f);  // n.p = -1: plane faces the camera
      Voxelizer dut(camera ? CameraSpace(0.0075f) : Euclidean(0.0075f));
      VoxelGrid grid;
      dut.Compute(cloud, true, &grid);
      ASSERT_GT(grid.size(), 1000u);
      const float len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
      size_t checked = 0, bad = 0;
      for (size_t v = 0; v < grid.size(); ++v) {
        // Voxels at the border of the image see only half a neighbourhood; still planar.
        const core::Vec3f& g = grid.normal[v];
        const float dot = (g.x * n.x + g.y * n.y + g.z * n.z) / len;
        const float towards =
            g.x * grid.centroid[v].x + g.y * grid.centroid[v].y + g.z * grid.centroid[v].z;
        EXPECT_LT(towards, 0.f);
        ++checked;
        if (dot < std::cos(2.0f * 3.14159265f / 180.f)) ++bad;
        EXPECT_LT(grid.curvature[v], 1e-3f);
      }
      EXPECT_EQ(bad, 0u) << "camera " << camera << " normal " << n.x << " " << n.y << " " << n.z;
      EXPECT_EQ(checked, grid.size());
    }
  }
}

TEST(VoxelGrid, ACornerHasHighCurvatureAndTwoNormalFamilies) {
  // Two perpendicular planes meeting in a vertical edge at x = 0.
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  core::PointCloud cloud;
  cloud.width = k.width;
  cloud.height = k.height;
  cloud.xyz.resize(static_cast<size_t>(k.width) * k.height);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const float rx = static_cast<float>((u - k.cx) / k.fx);
      const float ry = static_cast<float>((v - k.cy) / k.fy);
      // Planes z = 1.2 - x (x < 0) and z = 1.2 + x (x > 0): a ridge pointing at the camera.
      const float t = rx < 0.f ? 1.2f / (1.f + rx) : 1.2f / (1.f - rx);
      cloud.xyz[static_cast<size_t>(v) * k.width + u] = {rx * t, ry * t, t};
    }
  }
  Voxelizer dut(CameraSpace(0.0075f));
  VoxelGrid grid;
  dut.Compute(cloud, true, &grid);
  float max_curvature_at_edge = 0.f;
  for (size_t v = 0; v < grid.size(); ++v) {
    const core::Vec3f& c = grid.centroid[v];
    if (std::fabs(c.x) < 0.01f)
      max_curvature_at_edge = std::max(max_curvature_at_edge, grid.curvature[v]);
    if (std::fabs(c.x) > 0.05f) {
      EXPECT_LT(grid.curvature[v], 1e-3f);
      const float expected_nx = c.x < 0.f ? -0.7071f : 0.7071f;  // towards the camera
      EXPECT_NEAR(grid.normal[v].x, expected_nx, 0.03f);
    }
  }
  EXPECT_GT(max_curvature_at_edge, 0.02f);
}

TEST(VoxelGrid, OutputIsIdenticalForAnyPoolSizeAndReuse) {
  core::PointCloud cloud = PlaneCloud({0.2f, -0.5f, -0.84f}, -1.1f);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.f, 0.003f);
  for (auto& p : cloud.xyz) p.z += noise(rng);
  Voxelizer reference_dut(CameraSpace(0.0075f));
  VoxelGrid reference;
  reference_dut.Compute(cloud, true, &reference);
  for (int threads : {1, 2, 3}) {
    core::ThreadPool pool(threads);
    Voxelizer dut(CameraSpace(0.0075f), &pool);
    VoxelGrid grid;
    dut.Compute(RandomCloud(5, 3000), true, &grid);  // a different frame first
    dut.Compute(cloud, true, &grid);
    EXPECT_EQ(grid.point_voxel, reference.point_voxel) << threads;
    EXPECT_EQ(grid.key, reference.key);
    EXPECT_EQ(grid.num_points, reference.num_points);
    EXPECT_EQ(grid.point_sums, reference.point_sums);
    EXPECT_EQ(grid.adjacency_offsets, reference.adjacency_offsets);
    EXPECT_EQ(grid.adjacency, reference.adjacency);
    EXPECT_EQ(grid.curvature, reference.curvature);
    ASSERT_EQ(grid.size(), reference.size());
    for (size_t v = 0; v < grid.size(); ++v) {
      ASSERT_EQ(grid.normal[v].x, reference.normal[v].x);
      ASSERT_EQ(grid.normal[v].y, reference.normal[v].y);
      ASSERT_EQ(grid.normal[v].z, reference.normal[v].z);
      ASSERT_EQ(grid.centroid[v].z, reference.centroid[v].z);
    }
  }
}

// The grid of a cloud from first principles: the distinct quantised coordinates in
// lexicographic order, each with its points' count and sums added in point order.
void ExpectBruteForceGrid(const core::PointCloud& cloud, const Voxelizer& quantizer,
                          const VoxelGrid& grid) {
  std::map<std::tuple<int32_t, int32_t, int32_t>, std::pair<uint32_t, std::vector<double>>> ref;
  std::vector<std::tuple<int32_t, int32_t, int32_t>> point_coord(cloud.size());
  std::vector<bool> valid(cloud.size(), false);
  for (size_t i = 0; i < cloud.size(); ++i) {
    VoxelCoord c;
    if (!std::isfinite(cloud.xyz[i].x) || !std::isfinite(cloud.xyz[i].y) ||
        !std::isfinite(cloud.xyz[i].z) || !quantizer.Quantize(cloud.xyz[i], &c)) {
      continue;
    }
    valid[i] = true;
    point_coord[i] = {c.x, c.y, c.z};
    auto& entry = ref[point_coord[i]];
    entry.second.resize(9, 0.0);
    ++entry.first;
    AddToSums(cloud.xyz[i], entry.second.data());
  }
  ASSERT_EQ(grid.size(), ref.size());
  size_t v = 0;
  std::map<std::tuple<int32_t, int32_t, int32_t>, int32_t> index;
  for (const auto& [coord, entry] : ref) {
    EXPECT_EQ(grid.coord[v].x, std::get<0>(coord));
    EXPECT_EQ(grid.coord[v].y, std::get<1>(coord));
    ASSERT_EQ(grid.coord[v].z, std::get<2>(coord)) << v;
    EXPECT_EQ(grid.key[v], PackVoxelKey(grid.coord[v]));
    EXPECT_EQ(grid.num_points[v], entry.first);
    for (int j = 0; j < 9; ++j) ASSERT_EQ(grid.point_sums[9 * v + j], entry.second[j]) << v;
    index[coord] = static_cast<int32_t>(v++);
  }
  for (size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_EQ(grid.point_voxel[i], valid[i] ? index[point_coord[i]] : -1) << i;
  }
}

TEST(VoxelGrid, EqualsABruteForceGridForAnyPoolOnNarrowAndVeryWideClouds) {
  // An organized noisy plane in the camera space, and an unorganized cloud 40 m across on a
  // 7.5 mm Euclidean grid, whose (x, y) box of ~28 million columns is too large for one cell
  // per column.
  core::PointCloud plane = PlaneCloud({0.1f, -0.4f, -0.9f}, -1.0f);
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.f, 0.004f);
  for (auto& p : plane.xyz) p.z += noise(rng);
  core::PointCloud wide = RandomCloud(11, 20000);
  std::uniform_real_distribution<float> far(-20.f, 20.f);
  for (size_t i = 0; i < wide.size(); i += 7) wide.xyz[i] = {far(rng), far(rng), far(rng)};
  const std::vector<std::pair<const core::PointCloud*, VoxelGridParams>> cases = {
      {&plane, CameraSpace(0.0075f)}, {&wide, Euclidean(0.0075f)}};
  for (const auto& [cloud, params] : cases) {
    for (int threads : {1, 2, 4}) {
      core::ThreadPool pool(threads);
      Voxelizer dut(params, &pool);
      VoxelGrid grid;
      dut.Voxelize(*cloud, false, &grid);  // the first frame: even ranges of x
      ExpectBruteForceGrid(*cloud, dut, grid);
      dut.Voxelize(RandomCloud(2, 500), false, &grid);  // x counted in another frame's window
      dut.Voxelize(*cloud, false, &grid);
      ExpectBruteForceGrid(*cloud, dut, grid);
    }
  }
}

TEST(VoxelGrid, EmptyAndAllInvalidClouds) {
  Voxelizer dut(VoxelGridParams{});
  VoxelGrid grid;
  core::PointCloud empty;
  dut.Compute(empty, true, &grid);
  EXPECT_EQ(grid.size(), 0u);
  EXPECT_EQ(grid.adjacency_offsets, std::vector<uint32_t>{0});
  core::PointCloud nan_cloud;
  nan_cloud.width = 4;
  nan_cloud.height = 4;
  nan_cloud.xyz.assign(16, {kNaN, kNaN, kNaN});
  dut.Compute(nan_cloud, true, &grid);
  EXPECT_EQ(grid.size(), 0u);
  EXPECT_EQ(grid.point_voxel, std::vector<int32_t>(16, -1));
}

}  // namespace
}  // namespace clutterseg::geometry
