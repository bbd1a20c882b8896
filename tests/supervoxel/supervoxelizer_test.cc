#include "clutterseg/supervoxel/supervoxelizer.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "tests/supervoxel/purity.h"
#include "tests/supervoxel/synthetic_scene.h"

namespace clutterseg::supervoxel {
namespace {

using testing::DefaultBoxes;
using testing::RenderTableScene;
using testing::Scene;

Supervoxels Segment(const core::PointCloud& cloud, const SupervoxelParams& params = {},
                    core::ThreadPool* pool = nullptr) {
  Supervoxelizer dut(params, pool);
  Supervoxels out;
  dut.Compute(cloud, &out);
  return out;
}

void ExpectSameOutput(const Supervoxels& a, const Supervoxels& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.pixel_label, b.pixel_label);
  EXPECT_EQ(a.num_points, b.num_points);
  EXPECT_EQ(a.adjacency_offsets, b.adjacency_offsets);
  EXPECT_EQ(a.adjacency, b.adjacency);
  EXPECT_EQ(a.curvature, b.curvature);
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.centroid[i].x, b.centroid[i].x) << i;
    ASSERT_EQ(a.centroid[i].y, b.centroid[i].y) << i;
    ASSERT_EQ(a.centroid[i].z, b.centroid[i].z) << i;
    ASSERT_EQ(a.normal[i].x, b.normal[i].x) << i;
    ASSERT_EQ(a.normal[i].y, b.normal[i].y) << i;
    ASSERT_EQ(a.normal[i].z, b.normal[i].z) << i;
    ASSERT_EQ(a.eigenvalues[i].x, b.eigenvalues[i].x) << i;
    ASSERT_EQ(a.eigenvalues[i].z, b.eigenvalues[i].z) << i;
  }
}

// Structural invariants every output must satisfy.
void ExpectWellFormed(const core::PointCloud& cloud, const Supervoxels& sv) {
  const size_t n = sv.size();
  ASSERT_EQ(sv.pixel_label.size(), cloud.size());
  ASSERT_EQ(sv.normal.size(), n);
  ASSERT_EQ(sv.curvature.size(), n);
  ASSERT_EQ(sv.num_points.size(), n);
  ASSERT_EQ(sv.eigenvalues.size(), n);
  ASSERT_EQ(sv.adjacency_offsets.size(), n + 1);
  ASSERT_EQ(sv.adjacency_offsets.back(), sv.adjacency.size());
  std::vector<uint32_t> counted(n, 0);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const int32_t l = sv.pixel_label[i];
    if (core::IsValid(cloud.xyz[i])) {
      ASSERT_GE(l, 0) << "finite point " << i << " is unlabelled";
      ASSERT_LT(static_cast<size_t>(l), n);
      ++counted[static_cast<size_t>(l)];
    } else {
      ASSERT_EQ(l, -1) << "invalid point " << i << " is labelled";
    }
  }
  for (size_t s = 0; s < n; ++s) {
    EXPECT_EQ(counted[s], sv.num_points[s]) << s;
    EXPECT_GT(sv.num_points[s], 0u) << s;
    const core::Vec3f& nrm = sv.normal[s];
    EXPECT_NEAR(nrm.x * nrm.x + nrm.y * nrm.y + nrm.z * nrm.z, 1.0, 1e-4) << s;
    const core::Vec3f& c = sv.centroid[s];
    EXPECT_LE(nrm.x * c.x + nrm.y * c.y + nrm.z * c.z, 1e-6) << "normal away from camera " << s;
    EXPECT_GE(sv.curvature[s], 0.f);
    EXPECT_LE(sv.curvature[s], 1.f / 3.f + 1e-5f);
    // Sorted, no self loops, symmetric.
    for (uint32_t a = sv.adjacency_offsets[s]; a < sv.adjacency_offsets[s + 1]; ++a) {
      const uint32_t t = sv.adjacency[a];
      ASSERT_LT(t, n);
      EXPECT_NE(t, s);
      if (a > sv.adjacency_offsets[s]) {
        EXPECT_LT(sv.adjacency[a - 1], t);
      }
      const auto begin = sv.adjacency.begin() + sv.adjacency_offsets[t];
      const auto end = sv.adjacency.begin() + sv.adjacency_offsets[t + 1];
      EXPECT_TRUE(std::binary_search(begin, end, static_cast<uint32_t>(s)))
          << "edge " << s << "-" << t << " is not symmetric";
    }
  }
}

TEST(SupervoxelParams, ValidateRejectsBadValuesNamingTheKey) {
  EXPECT_NO_THROW(SupervoxelParams{}.ValidateOrThrow());
  auto message = [](const SupervoxelParams& p) {
    try {
      p.ValidateOrThrow();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  SupervoxelParams p;
  p.grid.voxel_resolution_m = 0.f;
  EXPECT_NE(message(p).find("voxel_resolution_m"), std::string::npos);
  p = {};
  p.seed_resolution_m = 0.001f;
  EXPECT_NE(message(p).find("seed_resolution_m"), std::string::npos);
  p = {};
  p.normal_importance = -1.f;
  EXPECT_NE(message(p).find("normal_importance"), std::string::npos);
  p = {};
  p.min_seed_occupancy = 2.f;
  EXPECT_NE(message(p).find("min_seed_occupancy"), std::string::npos);
  p = {};
  p.refinement_iterations = -1;
  EXPECT_NE(message(p).find("refinement_iterations"), std::string::npos);
  p = {};
  p.growth_regions = 0;
  EXPECT_NE(message(p).find("growth_regions"), std::string::npos);
  p = {};
  p.grid.voxel_resolution_m = -1.f;
  EXPECT_THROW(Supervoxelizer{p}, std::invalid_argument);
}

TEST(Supervoxelizer, EveryFinitePointIsLabelledOnATableScene) {
  for (double noise_mm : {0.0, 3.0}) {
    for (bool camera_transform : {true, false}) {
      const Scene scene = RenderTableScene(DefaultBoxes(), 0.8, 0.7, noise_mm);
      SupervoxelParams params;
      params.grid.use_single_camera_transform = camera_transform;
      Supervoxelizer dut(params);
      Supervoxels out;
      dut.Compute(scene.cloud, &out);
      SCOPED_TRACE(::testing::Message()
                   << "noise " << noise_mm << " transform " << camera_transform);
      ExpectWellFormed(scene.cloud, out);
      EXPECT_GT(out.size(), 100u);
      EXPECT_GT(dut.num_seeds(), 100u);
    }
  }
}

TEST(Supervoxelizer, StatisticsMatchTheMemberPoints) {
  const Scene scene = RenderTableScene(DefaultBoxes(), 0.8, 0.7, 2.0);
  const Supervoxels out = Segment(scene.cloud);
  const size_t n = out.size();
  std::vector<double> sum(3 * n, 0.0), sq(n, 0.0);
  std::vector<size_t> count(n, 0);
  for (size_t i = 0; i < scene.cloud.size(); ++i) {
    if (out.pixel_label[i] < 0) continue;
    const size_t s = static_cast<size_t>(out.pixel_label[i]);
    const core::Vec3f& p = scene.cloud.xyz[i];
    sum[3 * s] += p.x;
    sum[3 * s + 1] += p.y;
    sum[3 * s + 2] += p.z;
    ++count[s];
  }
  for (size_t i = 0; i < scene.cloud.size(); ++i) {
    if (out.pixel_label[i] < 0) continue;
    const size_t s = static_cast<size_t>(out.pixel_label[i]);
    const core::Vec3f& p = scene.cloud.xyz[i];
    const double dx = p.x - sum[3 * s] / count[s], dy = p.y - sum[3 * s + 1] / count[s],
                 dz = p.z - sum[3 * s + 2] / count[s];
    sq[s] += dx * dx + dy * dy + dz * dz;
  }
  for (size_t s = 0; s < n; ++s) {
    ASSERT_EQ(count[s], out.num_points[s]);
    EXPECT_NEAR(out.centroid[s].x, sum[3 * s] / count[s], 1e-5) << s;
    EXPECT_NEAR(out.centroid[s].y, sum[3 * s + 1] / count[s], 1e-5) << s;
    EXPECT_NEAR(out.centroid[s].z, sum[3 * s + 2] / count[s], 1e-5) << s;
    if (count[s] < 3) continue;
    // The eigenvalues sum to the trace of the covariance and are sorted.
    const core::Vec3f& l = out.eigenvalues[s];
    EXPECT_NEAR(l.x + l.y + l.z, sq[s] / count[s], 1e-7 + 1e-4 * sq[s] / count[s]) << s;
    EXPECT_GE(l.x, l.y);
    EXPECT_GE(l.y, l.z);
    EXPECT_NEAR(out.curvature[s], l.z / std::max(1e-12f, l.x + l.y + l.z), 1e-3) << s;
  }
}

TEST(Supervoxelizer, SupervoxelsOfAFlatPlaneMatchTheSeedSpacing) {
  // 1 m x 1 m at 1 m: an 800x800 camera with fx = 525 sees all of it.
  core::CameraIntrinsics k;
  k.width = 800;
  k.height = 800;
  k.cx = 399.5;
  k.cy = 399.5;
  const core::PointCloud cloud = testing::FrontalPlane(1.0, 0.5, k);
  for (bool camera_transform : {true, false}) {
    SupervoxelParams params;
    params.grid.use_single_camera_transform = camera_transform;
    const Supervoxels out = Segment(cloud, params);
    ExpectWellFormed(cloud, out);
    const double expected = 1.0 / (params.seed_resolution_m * params.seed_resolution_m);
    EXPECT_GT(out.size(), 0.7 * expected) << "transform " << camera_transform;
    EXPECT_LT(out.size(), 1.3 * expected) << "transform " << camera_transform;
    // Every supervoxel of a plane is flat and faces the camera.
    for (size_t s = 0; s < out.size(); ++s) {
      if (out.num_points[s] < 20) continue;
      EXPECT_LT(out.curvature[s], 1e-3f) << s;
      EXPECT_GT(-out.normal[s].z, 0.999f) << s;
    }
  }
}

TEST(Supervoxelizer, SupervoxelsAreConnectedInTheVoxelGraph) {
  for (double noise_mm : {0.0, 4.0}) {
    const Scene scene = RenderTableScene(DefaultBoxes(), 0.8, 0.7, noise_mm);
    Supervoxelizer dut{SupervoxelParams{}};
    Supervoxels out;
    dut.Compute(scene.cloud, &out);
    const geometry::VoxelGrid& g = dut.voxels();
    const std::vector<int32_t>& label = dut.voxel_label();
    ASSERT_EQ(label.size(), g.size());
    // Count, per supervoxel, the connected components of its voxels.
    std::vector<int> components(out.size(), 0);
    std::vector<uint8_t> seen(g.size(), 0);
    std::vector<uint32_t> queue;
    for (size_t v0 = 0; v0 < g.size(); ++v0) {
      if (seen[v0]) continue;
      ASSERT_GE(label[v0], 0);
      ++components[static_cast<size_t>(label[v0])];
      seen[v0] = 1;
      queue.assign(1, static_cast<uint32_t>(v0));
      for (size_t q = 0; q < queue.size(); ++q) {
        const uint32_t v = queue[q];
        for (uint32_t a = g.adjacency_offsets[v]; a < g.adjacency_offsets[v + 1]; ++a) {
          const uint32_t nb = g.adjacency[a];
          if (seen[nb] || label[nb] != label[v0]) continue;
          seen[nb] = 1;
          queue.push_back(nb);
        }
      }
    }
    for (size_t s = 0; s < out.size(); ++s) {
      EXPECT_EQ(components[s], 1) << "supervoxel " << s << " noise " << noise_mm;
    }
  }
}

TEST(Supervoxelizer, AdjacencyIsExactlyTheVoxelContacts) {
  const Scene scene = RenderTableScene(DefaultBoxes(), 0.8, 0.7, 2.0);
  Supervoxelizer dut{SupervoxelParams{}};
  Supervoxels out;
  dut.Compute(scene.cloud, &out);
  const geometry::VoxelGrid& g = dut.voxels();
  const std::vector<int32_t>& label = dut.voxel_label();
  std::vector<std::vector<uint32_t>> expected(out.size());
  for (size_t v = 0; v < g.size(); ++v) {
    for (uint32_t a = g.adjacency_offsets[v]; a < g.adjacency_offsets[v + 1]; ++a) {
      const int32_t l0 = label[v], l1 = label[g.adjacency[a]];
      if (l0 != l1) expected[static_cast<size_t>(l0)].push_back(static_cast<uint32_t>(l1));
    }
  }
  for (size_t s = 0; s < out.size(); ++s) {
    std::sort(expected[s].begin(), expected[s].end());
    expected[s].erase(std::unique(expected[s].begin(), expected[s].end()), expected[s].end());
    const std::vector<uint32_t> got(out.adjacency.begin() + out.adjacency_offsets[s],
                                    out.adjacency.begin() + out.adjacency_offsets[s + 1]);
    EXPECT_EQ(got, expected[s]) << s;
  }
  EXPECT_GT(out.num_edges(), out.size());  // a surface mesh has more edges than nodes
}

// Criterion: a supervoxel is "pure" when at least 90% of its points lie on one surface (the
// table or one box face). Voxels that straddle an edge make a few impure supervoxels
// unavoidable, but growth with the normal term must keep almost all on one face.
TEST(Supervoxelizer, SupervoxelsDoNotStraddleBoxEdges) {
  for (double noise_mm : {0.0, 2.0}) {
    const Scene scene = RenderTableScene(DefaultBoxes(), 0.8, 0.7, noise_mm);
    const Supervoxels out = Segment(scene.cloud);
    std::vector<std::map<int, int>> hist(out.size());
    for (size_t i = 0; i < scene.cloud.size(); ++i) {
      if (out.pixel_label[i] >= 0)
        ++hist[static_cast<size_t>(out.pixel_label[i])][scene.surface[i]];
    }
    int considered = 0, pure = 0, on_boxes = 0, pure_on_boxes = 0;
    for (const auto& h : hist) {
      int total = 0, best = 0;
      bool touches_box = false;
      for (const auto& [surface, count] : h) {
        total += count;
        best = std::max(best, count);
        touches_box |= surface > 0;
      }
      if (total < 20) continue;
      ++considered;
      const bool is_pure = best >= 0.9 * total;
      pure += is_pure;
      if (touches_box) {
        ++on_boxes;
        pure_on_boxes += is_pure;
      }
    }
    ASSERT_GT(on_boxes, 30);
    const double pure_fraction = static_cast<double>(pure) / considered;
    const double pure_box_fraction = static_cast<double>(pure_on_boxes) / on_boxes;
    EXPECT_GT(pure_fraction, 0.93) << "noise " << noise_mm;
    EXPECT_GT(pure_box_fraction, 0.85) << "noise " << noise_mm;
    std::printf("noise %.1f mm: %d supervoxels, pure %.3f, touching boxes %d, pure %.3f\n",
                noise_mm, considered, pure_fraction, on_boxes, pure_box_fraction);
  }
}

TEST(Supervoxelizer, OutputIsIdenticalForAnyPoolSize) {
  const Scene scene = RenderTableScene(DefaultBoxes(), 0.8, 0.7, 3.0);
  for (bool camera_transform : {true, false}) {
    for (float color : {0.f, 0.5f}) {
      for (int regions : {1, 2, 3}) {
        SupervoxelParams params;
        params.grid.use_single_camera_transform = camera_transform;
        params.color_importance = color;
        params.growth_regions = regions;
        const Supervoxels reference = Segment(scene.cloud, params, nullptr);
        for (int threads : {1, 2, 3}) {
          core::ThreadPool pool(threads);
          SCOPED_TRACE(::testing::Message()
                       << threads << " threads, transform " << camera_transform << ", colour "
                       << color << ", " << regions << " growth regions");
          ExpectSameOutput(reference, Segment(scene.cloud, params, &pool));
        }
      }
    }
  }
}

// Growth strips change where supervoxel borders fall, not what they respect: on the table
// scene every strip count keeps supervoxels on one box or the table.
TEST(Supervoxelizer, GrowthStripsKeepSupervoxelsPure) {
  const Scene scene = RenderTableScene(DefaultBoxes(), 0.8, 0.7, 0.0);
  for (int regions : {1, 2, 4}) {
    SupervoxelParams params;
    params.growth_regions = regions;
    const Supervoxels sv = Segment(scene.cloud, params, nullptr);
    ASSERT_GT(sv.size(), 50u);
    // Majority object (the table, or a box) of each supervoxel among its points.
    int impure = 0;
    for (const Purity& p : SupervoxelPurity(sv, [&](size_t i) {
           const int surface = scene.surface[i];
           return surface <= 0 ? surface : 1 + (surface - 1) / 6;
         })) {
      impure += static_cast<double>(p.majority) < 0.9 * static_cast<double>(p.total) ? 1 : 0;
    }
    EXPECT_LE(impure, static_cast<int>(sv.size()) / 50) << regions << " growth regions";
  }
}

TEST(Supervoxelizer, ReusedInstanceGivesTheSameResultAsAFreshOne) {
  const Scene a = RenderTableScene(DefaultBoxes(), 0.8, 0.7, 2.0);
  const Scene b = RenderTableScene({{-0.1, -0.1, 0.1, 0.1, 0.3}}, 1.2, 1.0, 1.0);
  core::ThreadPool pool(2);
  Supervoxelizer dut{SupervoxelParams{}, &pool};
  Supervoxels out;
  dut.Compute(a.cloud, &out);
  dut.Compute(b.cloud, &out);
  ExpectSameOutput(Segment(b.cloud), out);
  dut.Compute(a.cloud, &out);
  ExpectSameOutput(Segment(a.cloud), out);
}

TEST(Supervoxelizer, UsesColourWhenAskedTo) {
  // A flat plane whose left and right halves differ only in colour: with colour the
  // supervoxels respect the colour border, without they do not have to.
  core::CameraIntrinsics k;
  core::PointCloud cloud = testing::FrontalPlane(1.0, 0.3, k);
  cloud.rgba.resize(cloud.size());
  for (int v = 0; v < cloud.height; ++v) {
    for (int u = 0; u < cloud.width; ++u) {
      cloud.rgba[static_cast<size_t>(v) * cloud.width + u] =
          u < 320 ? core::PackRgba({250, 10, 10}) : core::PackRgba({10, 10, 250});
    }
  }
  auto mixed = [&](const Supervoxels& out) {
    std::vector<int> left(out.size(), 0), right(out.size(), 0);
    for (size_t i = 0; i < cloud.size(); ++i) {
      if (out.pixel_label[i] < 0) continue;
      (i % cloud.width < 320 ? left : right)[static_cast<size_t>(out.pixel_label[i])]++;
    }
    int count = 0;
    for (size_t s = 0; s < out.size(); ++s) count += std::min(left[s], right[s]) > 0;
    return count;
  };
  SupervoxelParams with_color;
  with_color.color_importance = 4.0f;
  // With colour only the voxels straddling the border column may mix (supervoxel count along
  // one border is about 0.6 m / 3 cm = 20).
  const Supervoxels colored = Segment(cloud, with_color);
  ExpectWellFormed(cloud, colored);
  EXPECT_LE(mixed(colored), 22);
  EXPECT_LT(mixed(colored), mixed(Segment(cloud)) + 1);
}

TEST(Supervoxelizer, DegenerateCloudsGiveValidTinyResults) {
  core::ThreadPool pool(2);
  Supervoxelizer dut{SupervoxelParams{}, &pool};
  Supervoxels out;

  core::PointCloud empty;
  dut.Compute(empty, &out);
  EXPECT_EQ(out.size(), 0u);
  EXPECT_TRUE(out.pixel_label.empty());
  ASSERT_EQ(out.adjacency_offsets.size(), 1u);

  core::PointCloud nan_cloud;
  nan_cloud.width = 64;
  nan_cloud.height = 48;
  nan_cloud.xyz.assign(64 * 48, {core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth});
  dut.Compute(nan_cloud, &out);
  EXPECT_EQ(out.size(), 0u);
  EXPECT_EQ(out.pixel_label, std::vector<int32_t>(64 * 48, -1));

  core::PointCloud one = nan_cloud;
  one.xyz[100] = {0.1f, 0.05f, 0.9f};
  dut.Compute(one, &out);
  ExpectWellFormed(one, out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out.pixel_label[100], 0);
  EXPECT_EQ(out.num_points[0], 1u);
  EXPECT_FLOAT_EQ(out.centroid[0].z, 0.9f);
  EXPECT_EQ(out.num_edges(), 0u);

  // Unorganized, with points behind the camera and far away (camera transform drops z <= 0).
  core::PointCloud loose;
  loose.width = 5;
  loose.height = 1;
  loose.xyz = {
      {0.f, 0.f, 1.f}, {0.001f, 0.f, 1.f}, {0.f, 0.f, -1.f}, {1e9f, 0.f, 1.f}, {0.f, 0.f, 50.f}};
  dut.Compute(loose, &out);
  ASSERT_EQ(out.pixel_label.size(), 5u);
  EXPECT_EQ(out.pixel_label[0], out.pixel_label[1]);
  EXPECT_GE(out.pixel_label[0], 0);
  EXPECT_GE(out.pixel_label[4], 0);
  EXPECT_EQ(out.pixel_label[2], -1);  // behind the camera: cannot be quantised
}

TEST(Supervoxelizer, UnseededComponentsBecomeTheirOwnSupervoxels) {
  // A plane plus stray points far from it and from each other: too sparse to keep a seed,
  // they must still be labelled, each as its own supervoxel.
  core::CameraIntrinsics k;
  core::PointCloud cloud = testing::FrontalPlane(1.0, 0.2, k);
  const size_t strays[] = {5, 600, 640 * 470 + 3};
  cloud.xyz[strays[0]] = {-0.5f, -0.4f, 0.9f};
  cloud.xyz[strays[1]] = {0.5f, -0.4f, 1.1f};
  // Single voxels are seeds only where a disc of radius seed_resolution / 2 holds few voxels
  // anyway (far away with the camera transform); at 1.2 m it still needs more than two.
  cloud.xyz[strays[2]] = {-0.5f, 0.4f, 1.2f};
  Supervoxelizer dut{SupervoxelParams{}};
  Supervoxels out;
  dut.Compute(cloud, &out);
  ExpectWellFormed(cloud, out);
  EXPECT_EQ(out.size(), dut.num_seeds() + 3);
  for (size_t i : strays) {
    const int32_t l = out.pixel_label[i];
    ASSERT_GE(l, static_cast<int32_t>(dut.num_seeds())) << "stray point joined a seeded supervoxel";
    EXPECT_EQ(out.num_points[static_cast<size_t>(l)], 1u);
    EXPECT_EQ(out.adjacency_offsets[l], out.adjacency_offsets[l + 1]);  // isolated
  }
  EXPECT_NE(out.pixel_label[strays[0]], out.pixel_label[strays[1]]);
  EXPECT_NE(out.pixel_label[strays[1]], out.pixel_label[strays[2]]);
}

}  // namespace
}  // namespace clutterseg::supervoxel
