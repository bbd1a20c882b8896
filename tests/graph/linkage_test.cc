#include "clutterseg/graph/linkage.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/geometry/voxel_grid.h"
#include "clutterseg/graph/patch_features.h"
#include "tests/graph/synthetic_tiles.h"

namespace clutterseg::graph {
namespace {

core::Vec3f Normalized(core::Vec3f v) {
  const float n = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return {v.x / n, v.y / n, v.z / n};
}

// A hand-made graph of patches: features and a CSR adjacency from an edge list.
struct HandGraph {
  supervoxel::Supervoxels sv;
  PatchFeatures f;

  int Add(core::Vec3f centroid, core::Vec3f normal, PatchType type) {
    const size_t i = f.size();
    f.Resize(i + 1);
    f.centroid[i] = centroid;
    f.normal[i] = Normalized(normal);
    f.type[i] = type;
    f.num_points[i] = 100;
    f.a2d[i] = type == PatchType::kPlanar ? 0.9f : 0.1f;
    sv.centroid.push_back(centroid);
    sv.normal.push_back(f.normal[i]);
    sv.curvature.push_back(0.f);
    sv.num_points.push_back(100);
    return static_cast<int>(i);
  }
  void Connect(const std::vector<std::pair<uint32_t, uint32_t>>& edges) {
    testing::BuildCsr(static_cast<int>(f.size()), edges, &sv.adjacency_offsets, &sv.adjacency);
  }
  // Kept flag of edge (i, j).
  int Kept(const LinkageResult& r, uint32_t i, uint32_t j) const { return Slot(r.edge_kept, i, j); }
  int Convex(const LinkageResult& r, uint32_t i, uint32_t j) const {
    return Slot(r.edge_convex, i, j);
  }
  int Slot(const std::vector<uint8_t>& v, uint32_t i, uint32_t j) const {
    for (uint32_t s = sv.adjacency_offsets[i]; s < sv.adjacency_offsets[i + 1]; ++s) {
      if (sv.adjacency[s] == j) return v[s];
    }
    return -1;
  }
};

const core::Vec3f kUp{0.f, -1.f, 0.f};      // table / box top normal (camera y points down)
const core::Vec3f kFacing{0.f, 0.f, -1.f};  // a face looking at the camera

TEST(IsConvexConnection, BoxEdgeIsConvex) {
  LinkageParams p;
  // Box top (y = 0.2) meets the box front face (z = 1.0) at a convex edge.
  EXPECT_TRUE(IsConvexConnection({0, 0.2f, 1.02f}, kUp, {0, 0.22f, 1.0f}, kFacing, p));
  EXPECT_TRUE(IsConvexConnection({0, 0.22f, 1.0f}, kFacing, {0, 0.2f, 1.02f}, kUp, p));
}

TEST(IsConvexConnection, TableCreaseIsConcave) {
  LinkageParams p;
  p.concavity_tolerance_deg = 10.f;  // LCCP's value
  // Front face (z = 1.0) standing on the table (y = 0.3): a concave crease.
  EXPECT_FALSE(IsConvexConnection({0, 0.28f, 1.0f}, kFacing, {0, 0.3f, 0.98f}, kUp, p));
  EXPECT_FALSE(IsConvexConnection({0, 0.3f, 0.98f}, kUp, {0, 0.28f, 1.0f}, kFacing, p));
  // The concavity tolerance accepts a shallow concavity (5 deg) but not a 20 deg one.
  const float a5 = 5.f * 3.14159265f / 180.f, a20 = 20.f * 3.14159265f / 180.f;
  const core::Vec3f tilted5{0, -std::cos(a5), -std::sin(a5)};
  const core::Vec3f tilted20{0, -std::cos(a20), -std::sin(a20)};
  // Patch j beyond patch i (farther in z), tilted towards the camera: a shallow valley.
  EXPECT_FALSE(IsConvexConnection({0, 0.3f, 1.0f}, kUp, {0, 0.3f, 1.03f}, tilted20, p));
  EXPECT_TRUE(IsConvexConnection({0, 0.3f, 1.0f}, kUp, {0, 0.3f, 1.03f}, tilted5, p));
  p.concavity_tolerance_deg = 2.f;
  EXPECT_FALSE(IsConvexConnection({0, 0.3f, 1.0f}, kUp, {0, 0.3f, 1.03f}, tilted5, p));
}

TEST(IsConvexConnection, SanityCriterionCutsNearParallelStep) {
  // Two patches side by side along x, 5 mm apart in height, normals 20 deg apart about x:
  // convex by the normal test, but the connection runs along the intersection line.
  const float a = 20.f * 3.14159265f / 180.f;
  const core::Vec3f ni = kUp;
  const core::Vec3f nj{0, -std::cos(a), -std::sin(a)};
  const core::Vec3f ci{0.f, 0.3f, 1.f}, cj{0.05f, 0.305f, 1.f};
  LinkageParams p;
  p.sanity_min_angle_deg = 0.f;  // LCCP: every connection is judged
  p.use_sanity_criterion = false;
  EXPECT_TRUE(IsConvexConnection(ci, ni, cj, nj, p));
  p.use_sanity_criterion = true;
  EXPECT_FALSE(IsConvexConnection(ci, ni, cj, nj, p));
  EXPECT_FALSE(IsConvexConnection(cj, nj, ci, ni, p));
  // The same normals with the connection across the crease line pass the sanity check.
  EXPECT_TRUE(IsConvexConnection({0, 0.2f, 1.02f}, kUp, {0, 0.22f, 1.0f}, kFacing, p));
}

TEST(IsConvexConnection, SanityCriterionOnlyFromItsMinimumAngle) {
  // Side by side along the line where the two patch planes meet, normals 15 deg apart: LCCP's
  // sanity criterion cuts it (its threshold at 15 deg is 4.6 deg; the connection runs 1.1 deg
  // off the line); from 20 deg on only, it stays.
  const float a = 15.f * 3.14159265f / 180.f;
  const core::Vec3f nj{0, -std::cos(a), -std::sin(a)};
  const core::Vec3f ci{0.f, 0.3f, 1.f}, cj{0.05f, 0.301f, 1.f};
  LinkageParams p;
  p.sanity_min_angle_deg = 0.f;
  EXPECT_FALSE(IsConvexConnection(ci, kUp, cj, nj, p));
  p.sanity_min_angle_deg = 20.f;
  EXPECT_TRUE(IsConvexConnection(ci, kUp, cj, nj, p));
  EXPECT_TRUE(IsConvexConnection(cj, nj, ci, kUp, p));
  // At 25 deg the criterion judges it again (and cuts: the line is 1.1 deg away).
  const float b = 25.f * 3.14159265f / 180.f;
  EXPECT_FALSE(IsConvexConnection(ci, kUp, cj, {0, -std::cos(b), -std::sin(b)}, p));
}

TEST(Linkage, BoxFacesKeptTableCreaseCut) {
  HandGraph g;
  const int table_a = g.Add({0, 0.3f, 0.95f}, kUp, PatchType::kPlanar);
  const int table_b = g.Add({0.03f, 0.3f, 0.95f}, kUp, PatchType::kPlanar);
  const int front_low = g.Add({0, 0.28f, 1.0f}, kFacing, PatchType::kPlanar);
  const int front_high = g.Add({0, 0.22f, 1.0f}, kFacing, PatchType::kPlanar);
  const int top = g.Add({0, 0.2f, 1.02f}, kUp, PatchType::kPlanar);
  g.Connect({{0, 1}, {0, 2}, {1, 2}, {2, 3}, {3, 4}});
  Linkage dut(LinkageParams{});
  LinkageResult r;
  dut.Compute(g.sv, g.f, &r);
  EXPECT_EQ(g.Kept(r, table_a, table_b), 1);
  EXPECT_EQ(g.Kept(r, table_b, table_a), 1);
  EXPECT_EQ(g.Kept(r, table_a, front_low), 0);
  EXPECT_EQ(g.Kept(r, front_low, table_b), 0);
  EXPECT_EQ(g.Kept(r, front_low, front_high), 1);
  EXPECT_EQ(g.Kept(r, front_high, top), 1);
  EXPECT_EQ(g.Convex(r, top, front_high), 1);
  ASSERT_EQ(r.num_segments, 2);
  EXPECT_EQ(r.segment[table_a], 0);
  EXPECT_EQ(r.segment[table_b], 0);
  EXPECT_EQ(r.segment[front_low], 1);
  EXPECT_EQ(r.segment[front_high], 1);
  EXPECT_EQ(r.segment[top], 1);
  EXPECT_EQ(r.segment_size, (std::vector<uint32_t>{2, 3}));
}

TEST(Linkage, TypeFilterIsAMajorityVote) {
  HandGraph g;
  // Node 0 (non-planar) with 3 planar neighbours of 4 becomes planar; node 5 (planar) with
  // one planar and one non-planar neighbour (a tie) keeps its type.
  g.Add({0, 0.3f, 1.f}, kUp, PatchType::kNonPlanar);
  g.Add({0.02f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({-0.02f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({0, 0.3f, 1.02f}, kUp, PatchType::kPlanar);
  g.Add({0, 0.3f, 0.98f}, kUp, PatchType::kNonPlanar);
  g.Add({0.1f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({0.12f, 0.3f, 1.f}, kUp, PatchType::kNonPlanar);
  g.Connect({{0, 1}, {0, 2}, {0, 3}, {0, 4}, {5, 1}, {5, 6}});
  LinkageResult r;
  Linkage(LinkageParams{}).Compute(g.sv, g.f, &r);
  EXPECT_EQ(r.filtered_type[0], PatchType::kPlanar);
  EXPECT_EQ(r.filtered_type[5], PatchType::kPlanar);
  // Node 4's only neighbour is node 0, non-planar before filtering; node 6 follows node 5.
  EXPECT_EQ(r.filtered_type[4], PatchType::kNonPlanar);
  EXPECT_EQ(r.filtered_type[6], PatchType::kPlanar);
  LinkageParams no_filter;
  no_filter.use_type_filter = false;
  no_filter.cut_on_type_change = true;  // the paper's rule
  Linkage(no_filter).Compute(g.sv, g.f, &r);
  EXPECT_EQ(r.filtered_type[0], PatchType::kNonPlanar);
  EXPECT_EQ(r.edge_kept[0], 0);  // 0-1: types differ -> cut
  LinkageParams no_type_cut = no_filter;
  no_type_cut.cut_on_type_change = false;
  Linkage(no_type_cut).Compute(g.sv, g.f, &r);
  EXPECT_EQ(r.num_segments, 1);
}

TEST(Linkage, ComponentsNumberedBySmallestSupervoxel) {
  HandGraph g;
  for (int i = 0; i < 6; ++i) g.Add({0.02f * i, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  // Components {0, 3, 5}, {1, 4}, {2}; coplanar patches, so every edge is kept.
  g.Connect({{5, 3}, {3, 0}, {4, 1}});
  LinkageResult r;
  Linkage(LinkageParams{}).Compute(g.sv, g.f, &r);
  EXPECT_EQ(r.num_segments, 3);
  EXPECT_EQ(r.segment, (std::vector<int32_t>{0, 1, 2, 0, 1, 0}));
  // Small components merge into their largest neighbour.
  g.Connect({{5, 3}, {3, 0}, {4, 1}, {2, 4}, {2, 3}});
  LinkageParams p;
  p.cut_on_type_change = true;
  p.min_segment_supervoxels = 1;
  HandGraph h = g;
  h.f.type[2] = PatchType::kNonPlanar;  // cut away by the type change (no filter majority)
  p.use_type_filter = false;
  Linkage(p).Compute(h.sv, h.f, &r);
  EXPECT_EQ(r.segment, (std::vector<int32_t>{0, 1, 2, 0, 1, 0}));
  p.min_segment_supervoxels = 2;
  Linkage(p).Compute(h.sv, h.f, &r);
  EXPECT_EQ(r.num_segments, 2);
  EXPECT_EQ(r.segment, (std::vector<int32_t>{0, 1, 0, 0, 1, 0}));  // 2 joins {0, 3, 5}
}

TEST(Linkage, ExtendedConvexityNeedsConvexTriangles) {
  HandGraph g;
  // A triangle of coplanar patches plus a pendant edge without common neighbours.
  g.Add({0, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({0.02f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({0.01f, 0.3f, 1.02f}, kUp, PatchType::kPlanar);
  g.Add({0.04f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Connect({{0, 1}, {1, 2}, {0, 2}, {1, 3}});
  LinkageParams p;
  p.use_extended_convexity = true;
  LinkageResult r;
  Linkage(p).Compute(g.sv, g.f, &r);
  EXPECT_EQ(g.Convex(r, 0, 1), 1);
  EXPECT_EQ(g.Convex(r, 1, 2), 1);
  EXPECT_EQ(g.Convex(r, 1, 3), 0);
  EXPECT_EQ(r.num_segments, 2);
}

TEST(Linkage, RejectsMalformedInput) {
  HandGraph g;
  g.Add({0, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({0.02f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.sv.adjacency_offsets = {0, 1, 1};  // 0 -> 1 without 1 -> 0
  g.sv.adjacency = {1};
  LinkageResult r;
  Linkage dut(LinkageParams{});
  EXPECT_THROW(dut.Compute(g.sv, g.f, &r), std::runtime_error);
  g.Connect({{0, 1}});
  PatchFeatures short_f = g.f;
  short_f.Resize(1);
  EXPECT_THROW(dut.Compute(g.sv, short_f, &r), std::runtime_error);
  LinkageParams bad;
  bad.min_segment_supervoxels = 0;
  EXPECT_THROW(Linkage{bad}, std::invalid_argument);
  bad = LinkageParams{};
  bad.concavity_tolerance_deg = -1.f;
  EXPECT_THROW(Linkage{bad}, std::invalid_argument);
}

// Renders a box on a table, tiles it and runs features + linkage.
struct SceneLinkage {
  testing::TabletopScene scene;
  core::PointCloud cloud;
  std::vector<int32_t> surface;
  supervoxel::Supervoxels sv;
  PatchFeatures f;
  std::vector<int32_t> pure;  // surface of >= 80% of a cell's pixels, or -2
};

SceneLinkage MakeScene() {
  SceneLinkage s;
  s.scene.wall_distance_m = 1.5;  // bounds the table before grazing, sparse depths
  // Faces on multiples of the 3 cm cell size, so that they lie mid cell.
  s.scene.boxes.push_back({{-0.12, 0.9, 0.0}, {0.06, 1.08, 0.15}});
  s.scene.boxes.push_back({{0.15, 0.96, 0.0}, {0.30, 1.05, 0.09}});
  testing::Render(s.scene, &s.cloud, &s.surface);
  // Cell boundaries 2 mm above the table: box faces start in their own cells.
  s.sv = testing::VoxelSupervoxels(s.scene, s.cloud, 0.03, 0.002);
  PatchFeatureExtractor().Compute(s.cloud, s.sv, &s.f);
  s.pure = testing::MajoritySurface(s.sv, s.surface, 0.8);
  return s;
}

TEST(Linkage, SceneSeparatesBoxesFromTable) {
  const SceneLinkage s = MakeScene();
  LinkageResult r;
  Linkage(LinkageParams{}).Compute(s.sv, s.f, &r);
  // The table's pure cells form one dominant segment that holds no pure box cell.
  std::map<int32_t, int> table_segments;
  int table_cells = 0;
  for (size_t i = 0; i < s.sv.size(); ++i) {
    if (s.pure[i] == testing::kSurfaceTable) {
      ++table_segments[r.segment[i]];
      ++table_cells;
    }
  }
  ASSERT_GT(table_cells, 300);
  const auto best = std::max_element(table_segments.begin(), table_segments.end(),
                                     [](auto a, auto b) { return a.second < b.second; });
  const int32_t table_segment = best->first;
  EXPECT_GT(best->second, 0.97 * table_cells);
  // Edges inside a box are convex; edges between a box and the table are not.
  int box_edges = 0, box_convex = 0, crease_edges = 0, crease_convex = 0;
  std::map<int32_t, std::map<int32_t, int>> box_segments;  // box -> segment -> cells
  for (size_t i = 0; i < s.sv.size(); ++i) {
    if (s.pure[i] >= testing::kSurfaceBox0) {
      EXPECT_NE(r.segment[i], table_segment) << "box cell " << i;
      ++box_segments[s.pure[i]][r.segment[i]];
    }
    for (uint32_t k = s.sv.adjacency_offsets[i]; k < s.sv.adjacency_offsets[i + 1]; ++k) {
      const uint32_t j = s.sv.adjacency[k];
      if (s.pure[i] >= testing::kSurfaceBox0 && s.pure[j] == s.pure[i]) {
        ++box_edges;
        box_convex += r.edge_convex[k];
      }
      if (s.pure[i] >= testing::kSurfaceBox0 && s.pure[j] == testing::kSurfaceTable) {
        ++crease_edges;
        crease_convex += r.edge_convex[k];
      }
    }
  }
  ASSERT_GT(box_edges, 100);
  ASSERT_GE(crease_edges, 5);               // one per bottom cell of the front faces
  EXPECT_GT(box_convex, 0.95 * box_edges);  // a few sliver cells on box edges are noisy
  EXPECT_EQ(crease_convex, 0);
  // Each box's largest segment is its own.
  ASSERT_EQ(box_segments.size(), 2u);
  std::vector<int32_t> dominant;
  for (const auto& [box, segs] : box_segments) {
    int total = 0;
    for (const auto& [seg, c] : segs) total += c;
    const auto it = std::max_element(segs.begin(), segs.end(),
                                     [](auto a, auto b) { return a.second < b.second; });
    EXPECT_GT(it->second, 0.5 * total) << "box " << box;
    dominant.push_back(it->first);
  }
  EXPECT_NE(dominant[0], dominant[1]);
}

// Two flat supervoxels facing the camera side by side (left: x < 0, right: x >= 0), the right
// one `step_m` behind the left except along the top `touch_rows` rows of an organized
// `width` x `height` image, where both lie at 1 m: the right one stands behind and touches the
// left at one end, as an object standing behind another. Coplanar normals make the
// connection convex. `organized` false: the same points, unorganized, in a shuffled order.
struct StepScene {
  core::PointCloud cloud;
  supervoxel::Supervoxels sv;
  PatchFeatures f;
};

StepScene MakeStep(double step_m, int touch_rows, bool organized, int width = 80, int height = 60) {
  StepScene s;
  const double f = 525.0, cx = 0.5 * (width - 1), cy = 0.5 * (height - 1);
  std::vector<std::pair<core::Vec3f, int32_t>> points;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const bool right = u >= width / 2;
      const double z = right && v >= touch_rows ? 1.0 + step_m : 1.0;
      const core::Vec3f p{static_cast<float>((u - cx) * z / f),
                          static_cast<float>((v - cy) * z / f), static_cast<float>(z)};
      points.emplace_back(p, right ? 1 : 0);
    }
  }
  if (!organized) {
    std::mt19937 rng(3);
    std::shuffle(points.begin(), points.end(), rng);
  }
  s.cloud.width = organized ? width : width * height;
  s.cloud.height = organized ? height : 1;
  s.sv.width = s.cloud.width;
  s.sv.height = s.cloud.height;
  for (const auto& [p, label] : points) {
    s.cloud.xyz.push_back(p);
    s.sv.pixel_label.push_back(label);
  }
  testing::BuildCsr(2, {{0, 1}}, &s.sv.adjacency_offsets, &s.sv.adjacency);
  s.sv.centroid.resize(2);
  s.sv.normal.assign(2, kFacing);
  s.sv.curvature.assign(2, 0.f);
  s.sv.num_points.assign(2, 0);
  s.sv.eigenvalues.resize(2);
  PatchFeatureExtractor().Compute(s.cloud, s.sv, &s.f);
  s.f.normal.assign(2, kFacing);
  return s;
}

// Kept flag of the one edge with the cues of `s` (for an unorganized cloud: its voxels and,
// for each voxel, the side its points lie on).
int StepEdgeKept(const StepScene& s, const LinkageParams& params, bool camera_transform,
                 core::ThreadPool* pool = nullptr) {
  LinkageCues cues;
  cues.cloud = s.cloud;
  geometry::VoxelGridParams gp;
  gp.use_single_camera_transform = camera_transform;
  geometry::Voxelizer voxelizer(gp);
  geometry::VoxelGrid grid;
  std::vector<int32_t> owner;
  if (!s.cloud.organized()) {
    voxelizer.Compute(s.cloud, false, &grid);
    for (size_t v = 0; v < grid.size(); ++v) owner.push_back(grid.centroid[v].x < 0.f ? 0 : 1);
    cues.voxels = &grid;
    cues.voxel_supervoxel = &owner;
  }
  Linkage dut(params, pool);
  LinkageResult r;
  dut.Compute(s.sv, s.f, cues, &r);
  EXPECT_EQ(r.num_segments, r.edge_kept[0] ? 1 : 2);
  return r.edge_kept[0];
}

TEST(Linkage, DepthJumpCutsTouchingSurfacesOneBehindTheOther) {
  LinkageParams off;
  off.depth_jump_rel = 0.f;
  const LinkageParams on;  // 2 % of the depth, half the border pairs, at least 3
  for (const bool organized : {true, false}) {
    for (const bool camera : {true, false}) {
      if (organized && !camera) continue;  // the grid only matters without pixels
      SCOPED_TRACE(organized ? "organized"
                   : camera  ? "unorganized, voxel columns"
                             : "unorganized, view-direction tree");
      // 5 cm behind along 52 of 60 rows: cut; without the cue the convex edge stays.
      const StepScene step = MakeStep(0.05, 8, organized);
      EXPECT_EQ(StepEdgeKept(step, off, camera), 1);
      EXPECT_EQ(StepEdgeKept(step, on, camera), 0);
      // Touching along the whole border: no jump, kept.
      EXPECT_EQ(StepEdgeKept(MakeStep(0.0, 0, organized), on, camera), 1);
      // A 1 cm step is below 2 % of 1 m: kept; at 0.5 % it is a jump.
      const StepScene small = MakeStep(0.01, 8, organized);
      EXPECT_EQ(StepEdgeKept(small, on, camera), 1);
      LinkageParams fine = on;
      fine.depth_jump_rel = 0.005f;
      EXPECT_EQ(StepEdgeKept(small, fine, camera), 0);
      // Touching along most of the border: the jumping share is below one half.
      EXPECT_EQ(StepEdgeKept(MakeStep(0.05, 45, organized), on, camera), 1);
    }
  }
}

TEST(Linkage, CreaseEvidenceCutsAMildConcavityNextToASharpOne) {
  // i on a flat floor, j on a 30 deg slope beside it (concave, within the 35 deg tolerance),
  // k a patch touching both that meets i at 60 deg (a sharp concavity): the mild edge is a
  // stretch of the same crease.
  HandGraph g;
  const float b = 30.f * 3.14159265f / 180.f, c = 60.f * 3.14159265f / 180.f;
  const int i = g.Add({0.f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  const int j = g.Add({0.03f, 0.295f, 1.f}, {-std::sin(b), -std::cos(b), 0.f}, PatchType::kPlanar);
  g.Add({0.015f, 0.28f, 1.f}, {-std::sin(c), -std::cos(c), 0.f}, PatchType::kPlanar);
  g.Connect({{0, 1}, {0, 2}, {1, 2}});
  LinkageParams p;
  LinkageResult r;
  Linkage(p).Compute(g.sv, g.f, &r);
  EXPECT_EQ(g.Kept(r, i, j), 1);  // off by default
  EXPECT_EQ(g.Kept(r, i, 2), 0);  // the sharp concavity
  p.crease_min_angle_deg = 25.f;
  Linkage(p).Compute(g.sv, g.f, &r);
  EXPECT_EQ(g.Kept(r, i, j), 0);
  EXPECT_EQ(g.Kept(r, j, i), 0);
  // Below its minimum angle the mild concavity stays.
  p.crease_min_angle_deg = 31.f;
  Linkage(p).Compute(g.sv, g.f, &r);
  EXPECT_EQ(g.Kept(r, i, j), 1);
  // Without the sharp neighbour there is no evidence.
  HandGraph h;
  h.Add({0.f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  h.Add({0.03f, 0.295f, 1.f}, {-std::sin(b), -std::cos(b), 0.f}, PatchType::kPlanar);
  h.Connect({{0, 1}});
  p.crease_min_angle_deg = 25.f;
  Linkage(p).Compute(h.sv, h.f, &r);
  EXPECT_EQ(h.Kept(r, 0, 1), 1);
}

TEST(Linkage, ColourCutsConcaveEdgesBetweenDifferentColours) {
  // The mild concavity of the crease test and a convex box edge, each between a red and a
  // blue patch (10 points each): only the concave one is cut, and only when asked.
  HandGraph g;
  const float b = 30.f * 3.14159265f / 180.f;
  g.Add({0.f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({0.03f, 0.295f, 1.f}, {-std::sin(b), -std::cos(b), 0.f}, PatchType::kPlanar);
  g.Add({0, 0.2f, 1.02f}, kUp, PatchType::kPlanar);
  g.Add({0, 0.22f, 1.0f}, kFacing, PatchType::kPlanar);
  g.Connect({{0, 1}, {2, 3}});
  core::PointCloud cloud;
  cloud.width = 40;
  cloud.height = 1;
  for (int k = 0; k < 40; ++k) {
    const int patch = k / 10;
    g.sv.pixel_label.push_back(patch);
    cloud.xyz.push_back(g.f.centroid[patch]);
    // Red patches 0 and 2 (a little noise), blue 1 and 3.
    cloud.rgba.push_back(patch % 2 == 0 ? 0xffc81e14u + static_cast<uint32_t>(k % 3) : 0xff1e28c8u);
  }
  g.sv.width = 40;
  g.sv.height = 1;
  LinkageCues cues;
  cues.cloud = cloud;
  LinkageParams p;
  p.color_threshold = 0.f;
  LinkageResult r;
  Linkage(p).Compute(g.sv, g.f, cues, &r);
  EXPECT_EQ(g.Kept(r, 0, 1), 1);  // off
  p.color_threshold = 25.f;
  p.color_min_angle_deg = 20.f;
  Linkage(p).Compute(g.sv, g.f, cues, &r);
  EXPECT_EQ(g.Kept(r, 0, 1), 0);
  EXPECT_EQ(g.Kept(r, 2, 3), 1);  // convex: colour alone never cuts it
  // The same colour on both sides: kept.
  for (uint32_t& c : cloud.rgba) c = 0xffc81e14u;
  Linkage(p).Compute(g.sv, g.f, cues, &r);
  EXPECT_EQ(g.Kept(r, 0, 1), 1);
}

TEST(Linkage, ColourWidensTheConcavityToleranceOnlyBetweenPatchesOfOneColour) {
  // A 50 degree concavity (beyond the 35 degree tolerance): the inside of a bowl when both
  // patches have one colour, a contact when they differ. With the tolerance at 60 with
  // colour (off by default) and the colour cut from 35 degrees it is kept only in the first
  // case, and cut whatever the colours when the cloud has none.
  HandGraph g;
  const float b = 50.f * 3.14159265f / 180.f;
  g.Add({0.f, 0.3f, 1.f}, kUp, PatchType::kPlanar);
  g.Add({0.03f, 0.295f, 1.f}, {-std::sin(b), -std::cos(b), 0.f}, PatchType::kPlanar);
  g.Connect({{0, 1}});
  core::PointCloud cloud;
  cloud.width = 20;
  cloud.height = 1;
  for (int k = 0; k < 20; ++k) {
    g.sv.pixel_label.push_back(k / 10);
    cloud.xyz.push_back(g.f.centroid[static_cast<size_t>(k / 10)]);
    cloud.rgba.push_back(0xffc81e14u);
  }
  g.sv.width = 20;
  g.sv.height = 1;
  LinkageCues cues;
  cues.cloud = cloud;
  LinkageParams p;
  EXPECT_EQ(p.color_concavity_tolerance_deg, 0.f);  // off by default (docs/method.md)
  p.color_concavity_tolerance_deg = 60.f;
  ASSERT_LT(p.concavity_tolerance_deg, 50.f);
  LinkageResult r;
  Linkage(p).Compute(g.sv, g.f, cues, &r);
  EXPECT_EQ(g.Kept(r, 0, 1), 1);  // one colour
  for (int k = 10; k < 20; ++k) cloud.rgba[static_cast<size_t>(k)] = 0xff1e28c8u;
  Linkage(p).Compute(g.sv, g.f, cues, &r);
  EXPECT_EQ(g.Kept(r, 0, 1), 0);  // two colours
  cloud.rgba.clear();
  cues.cloud = cloud;  // the view sees the cloud as it is when taken
  Linkage(p).Compute(g.sv, g.f, cues, &r);
  EXPECT_EQ(g.Kept(r, 0, 1), 0);  // no colour: the 35 degree tolerance
  LinkageParams off = p;
  off.color_concavity_tolerance_deg = 0.f;
  for (int k = 0; k < 20; ++k) cloud.rgba.push_back(0xffc81e14u);
  cues.cloud = cloud;
  Linkage(off).Compute(g.sv, g.f, cues, &r);
  EXPECT_EQ(g.Kept(r, 0, 1), 0);  // one colour, but the wider tolerance off
}

// A floor of 5 x 4 patches and a wall of 5 x 4 standing on it: along four columns the two
// meet at a sharp crease (cut); along the fifth a rounded corner of two patches (30 degree
// steps, kept by the concavity tolerance) joins them: one component held by a one-edge bridge.
// `crease_columns` of the four sharp columns have a floor-wall edge.
struct BridgeScene {
  HandGraph g;
  std::vector<int> floor, wall;
};
BridgeScene MakeBridgeScene(int crease_columns) {
  BridgeScene b;
  const float rad = 3.14159265f / 180.f;
  for (int row = 0; row < 4; ++row) {
    for (int col = 0; col < 5; ++col) {
      b.floor.push_back(b.g.Add({0.03f * col, 0.3f, 0.98f + 0.03f * row}, kUp, PatchType::kPlanar));
    }
  }
  for (int row = 0; row < 4; ++row) {
    for (int col = 0; col < 5; ++col) {
      b.wall.push_back(
          b.g.Add({0.03f * col, 0.28f - 0.03f * row, 1.1f}, kFacing, PatchType::kPlanar));
    }
  }
  const int a = b.g.Add({0.12f, 0.297f, 1.085f}, {0.f, -std::cos(30 * rad), -std::sin(30 * rad)},
                        PatchType::kPlanar);
  const int c = b.g.Add({0.12f, 0.29f, 1.095f}, {0.f, -std::cos(60 * rad), -std::sin(60 * rad)},
                        PatchType::kPlanar);
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  const auto grid = [&](const std::vector<int>& ids) {
    for (int row = 0; row < 4; ++row) {
      for (int col = 0; col < 5; ++col) {
        const auto i = static_cast<uint32_t>(ids[static_cast<size_t>(row * 5 + col)]);
        if (col < 4) edges.emplace_back(i, i + 1);
        if (row < 3) edges.emplace_back(i, i + 5);
      }
    }
  };
  grid(b.floor);
  grid(b.wall);
  for (int col = 0; col < crease_columns; ++col) {  // the floor's last row meets the wall's first
    edges.emplace_back(static_cast<uint32_t>(b.floor[static_cast<size_t>(15 + col)]),
                       static_cast<uint32_t>(b.wall[static_cast<size_t>(col)]));
  }
  edges.emplace_back(static_cast<uint32_t>(b.floor[19]), static_cast<uint32_t>(a));
  edges.emplace_back(static_cast<uint32_t>(a), static_cast<uint32_t>(c));
  edges.emplace_back(static_cast<uint32_t>(c), static_cast<uint32_t>(b.wall[4]));
  b.g.Connect(edges);
  return b;
}

TEST(Linkage, BridgeCutSeparatesPartsHeldOnlyByANarrowBridge) {
  const BridgeScene b = MakeBridgeScene(4);
  LinkageParams p;
  p.bridge_max_edges = 0;
  LinkageResult r;
  Linkage(p).Compute(b.g.sv, b.g.f, &r);
  // Without the cut: the crease is cut, the rounded corner kept, and all is one segment.
  for (int col = 0; col < 4; ++col) {
    EXPECT_EQ(b.g.Kept(r, static_cast<uint32_t>(b.floor[static_cast<size_t>(15 + col)]),
                       static_cast<uint32_t>(b.wall[static_cast<size_t>(col)])),
              0);
  }
  EXPECT_EQ(b.g.Kept(r, 40, 41), 1);  // the corner: patches 40 and 41
  ASSERT_EQ(r.num_segments, 1);
  // The defaults cut the bridge: four crease edges against one bridge edge.
  Linkage(LinkageParams{}).Compute(b.g.sv, b.g.f, &r);
  ASSERT_EQ(r.num_segments, 2);
  for (const int i : b.floor) EXPECT_EQ(r.segment[static_cast<size_t>(i)], r.segment[0]);
  for (const int i : b.wall) EXPECT_NE(r.segment[static_cast<size_t>(i)], r.segment[0]);
  int cut = 0;
  for (const auto& [i, j] :
       std::vector<std::pair<uint32_t, uint32_t>>{{19, 40}, {40, 41}, {41, 24}}) {
    EXPECT_EQ(b.g.Kept(r, i, j), b.g.Kept(r, j, i));
    cut += b.g.Kept(r, i, j) == 0 ? 1 : 0;
  }
  EXPECT_EQ(cut, 1);  // one edge of the bridge, nothing else
}

TEST(Linkage, BridgeCutNeedsALongCreaseLargeSidesAndAFlatBridge) {
  LinkageResult r;
  {
    // Two crease edges against one bridge edge: below bridge_min_crease_ratio (3).
    const BridgeScene b = MakeBridgeScene(2);
    Linkage(LinkageParams{}).Compute(b.g.sv, b.g.f, &r);
    EXPECT_EQ(r.num_segments, 1);
    LinkageParams p;
    p.bridge_min_crease_ratio = 2.f;
    Linkage(p).Compute(b.g.sv, b.g.f, &r);
    EXPECT_EQ(r.num_segments, 2);
  }
  const BridgeScene b = MakeBridgeScene(4);
  LinkageParams p;
  p.bridge_min_supervoxels = 21;  // the floor (and the corner's patches) are 20-22 supervoxels
  Linkage(p).Compute(b.g.sv, b.g.f, &r);
  EXPECT_EQ(r.num_segments, 1);
  p = LinkageParams{};
  p.bridge_max_angle_deg = 25.f;  // the corner turns by 30 degrees at every edge
  Linkage(p).Compute(b.g.sv, b.g.f, &r);
  EXPECT_EQ(r.num_segments, 1);
  p = LinkageParams{};
  // The corner's concave edges are 1 or 2 of the 32 or 33 kept edges of a side: a side is a
  // concave surface (a vessel's inside) only from a share below that.
  p.bridge_max_concave_share = 0.02f;
  Linkage(p).Compute(b.g.sv, b.g.f, &r);
  EXPECT_EQ(r.num_segments, 1);
  p.bridge_max_concave_share = 0.1f;
  Linkage(p).Compute(b.g.sv, b.g.f, &r);
  EXPECT_EQ(r.num_segments, 2);
}

// Two rows of flat strips facing the camera at 1 m in an organized 80 x 60 image: strips
// 0..left-1 from the left edge and left..left+right-1 after a gap of 8 columns of invalid
// pixels (the top of a thin wall seen edge-on, a shadow), 9 columns each. Neighbouring strips of
// a side touch; the two innermost strips are neighbours in space (edge (left - 1, left))
// although no pixel of one touches a pixel of the other: two faces of one surface height on
// either side of a wall, as a cup's inside bottom and the book it stands on. `contact`: pixels
// of the gap filled on row 30 so that the two strips touch there, 4-neighbour (1) or only
// diagonally (2). The right side's normals are turned by `turn_deg` about the image vertical.
StepScene MakeWall(int left, int right, int contact, float turn_deg) {
  constexpr int kWidth = 80, kHeight = 60, kStrip = 9, kGap = 8;
  StepScene s;
  const double f = 525.0, cx = 0.5 * (kWidth - 1), cy = 0.5 * (kHeight - 1);
  const int gap_begin = left * kStrip, gap_end = gap_begin + kGap;
  const int n = left + right;
  s.cloud.width = s.sv.width = kWidth;
  s.cloud.height = s.sv.height = kHeight;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      int32_t label = -1;
      if (u < gap_begin) {
        label = u / kStrip;
      } else if (u >= gap_end && u < gap_end + right * kStrip) {
        label = left + (u - gap_end) / kStrip;
      }
      const int half = gap_begin + kGap / 2;
      if (contact == 1 && v == 30 && u >= gap_begin && u < gap_end) {
        label = u < half ? left - 1 : left;
      }
      if (contact == 2 && u >= gap_begin && u < gap_end &&
          ((v == 30 && u < half) || (v == 31 && u >= half))) {
        label = u < half ? left - 1 : left;
      }
      s.sv.pixel_label.push_back(label);
      s.cloud.xyz.push_back(label < 0 ? core::Vec3f{nan, nan, nan}
                                      : core::Vec3f{static_cast<float>((u - cx) / f),
                                                    static_cast<float>((v - cy) / f), 1.f});
    }
  }
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  for (int i = 0; i + 1 < n; ++i) edges.emplace_back(i, i + 1);
  testing::BuildCsr(n, edges, &s.sv.adjacency_offsets, &s.sv.adjacency);
  s.sv.centroid.resize(static_cast<size_t>(n));
  s.sv.normal.assign(static_cast<size_t>(n), kFacing);
  s.sv.curvature.assign(static_cast<size_t>(n), 0.f);
  s.sv.num_points.assign(static_cast<size_t>(n), 0);
  s.sv.eigenvalues.resize(static_cast<size_t>(n));
  PatchFeatureExtractor().Compute(s.cloud, s.sv, &s.f);
  const float t = turn_deg * std::numbers::pi_v<float> / 180.f;
  for (int i = 0; i < n; ++i) {
    s.f.normal[static_cast<size_t>(i)] =
        i < left ? kFacing : core::Vec3f{std::sin(t), 0.f, -std::cos(t)};
  }
  return s;
}

int WallSegments(const StepScene& s, const LinkageParams& params) {
  LinkageCues cues;
  cues.cloud = s.cloud;
  LinkageResult r;
  Linkage(params).Compute(s.sv, s.f, cues, &r);
  return r.num_segments;
}

TEST(Linkage, ContactCutSeparatesParallelFacesThatDoNotTouchInTheImage) {
  LinkageParams off;
  off.contact_cut_max_pairs = 0;
  const LinkageParams on;  // fewer than 1 pixel pair, within 25.84 deg, sides of 4 or more
  // Four strips on each side, no pixel contact: one segment without the cut, two with it.
  const StepScene wall = MakeWall(4, 4, 0, 0.f);
  ASSERT_EQ(WallSegments(wall, off), 1);
  EXPECT_EQ(WallSegments(wall, on), 2);
  // The strips touch on one row, side by side or only at a corner: they are seen to touch.
  EXPECT_EQ(WallSegments(MakeWall(4, 4, 1, 0.f), on), 1);
  EXPECT_EQ(WallSegments(MakeWall(4, 4, 2, 0.f), on), 1);
  // ...unless more contact is asked for: one row gives one pair of pixels either way.
  LinkageParams more = on;
  more.contact_cut_max_pairs = 2;
  EXPECT_EQ(WallSegments(MakeWall(4, 4, 1, 0.f), more), 2);
  EXPECT_EQ(WallSegments(MakeWall(4, 4, 2, 0.f), more), 2);
  // Faces turned by 30 degrees to each other are left to the convexity test, which keeps them.
  const StepScene turned = MakeWall(4, 4, 0, 30.f);
  ASSERT_EQ(WallSegments(turned, off), 1);
  EXPECT_EQ(WallSegments(turned, on), 1);
  // A side of 3 strips is below contact_cut_min_supervoxels (4): the edge is kept.
  const StepScene small = MakeWall(4, 3, 0, 0.f);
  ASSERT_EQ(WallSegments(small, off), 1);
  EXPECT_EQ(WallSegments(small, on), 1);
  LinkageParams smaller = on;
  smaller.contact_cut_min_supervoxels = 3;
  EXPECT_EQ(WallSegments(small, smaller), 2);
}

TEST(Linkage, IdenticalForAnyThreadCount) {
  const SceneLinkage s = MakeScene();
  LinkageParams p;
  p.use_extended_convexity = true;
  p.min_segment_supervoxels = 3;
  p.crease_min_angle_deg = 25.f;
  LinkageCues cues;  // depth jumps across the image border
  cues.cloud = s.cloud;
  LinkageResult reference;
  Linkage(p).Compute(s.sv, s.f, cues, &reference);
  for (int threads : {1, 2, 3}) {
    core::ThreadPool pool(threads);
    Linkage dut(p, &pool);
    LinkageResult r;
    dut.Compute(s.sv, s.f, cues, &r);
    EXPECT_EQ(r.segment, reference.segment);
    EXPECT_EQ(r.edge_kept, reference.edge_kept);
    EXPECT_EQ(r.edge_convex, reference.edge_convex);
    EXPECT_EQ(r.num_segments, reference.num_segments);
  }
  // Edge flags are symmetric.
  for (size_t i = 0; i < s.sv.size(); ++i) {
    for (uint32_t k = s.sv.adjacency_offsets[i]; k < s.sv.adjacency_offsets[i + 1]; ++k) {
      const uint32_t j = s.sv.adjacency[k];
      const auto first = s.sv.adjacency.begin() + s.sv.adjacency_offsets[j];
      const auto last = s.sv.adjacency.begin() + s.sv.adjacency_offsets[j + 1];
      const size_t back =
          std::lower_bound(first, last, static_cast<uint32_t>(i)) - s.sv.adjacency.begin();
      ASSERT_EQ(reference.edge_kept[k], reference.edge_kept[back]);
    }
  }
}

}  // namespace
}  // namespace clutterseg::graph
