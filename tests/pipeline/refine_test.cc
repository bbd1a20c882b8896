#include "clutterseg/pipeline/refine.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numeric>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::pipeline {
namespace {

using graph::PatchType;

// Half-open pixel rectangle [u0, u1) x [v0, v1).
struct Block {
  int u0, v0, u1, v1;
};

constexpr core::Vec3f kFacing{0.f, 0.f, -1.f};

// A hand-made frame for the Refiner: an organized w x h image whose supervoxels are pixel
// rectangles at given depths, with their features, initial segments, planes and adjacency
// set by hand. The table is the plane z = 1 m facing the camera (plane 0: normal (0, 0, -1),
// d = 1, so a point nearer the camera is above it).
class HandFrame {
 public:
  HandFrame(int w, int h) : w_(w), h_(h) {
    k_.width = w;
    k_.height = h;
    k_.cx = 0.5 * (w - 1);
    k_.cy = 0.5 * (h - 1);
    cloud_.width = w;
    cloud_.height = h;
    const core::Vec3f invalid{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth};
    cloud_.xyz.assign(static_cast<size_t>(w) * h, invalid);
    sv_.width = w;
    sv_.height = h;
    sv_.pixel_label.assign(static_cast<size_t>(w) * h, -1);
    planes_.planes.push_back(optimize::PlaneModel{kFacing, 1.f, 0, 0});
  }

  // A plane n . x + d = 0; returns its index.
  int AddPlane(const core::Vec3f& n, float d) {
    planes_.planes.push_back(optimize::PlaneModel{n, d, 0, 0});
    return static_cast<int>(planes_.planes.size()) - 1;
  }

  // A supervoxel over the pixels of `b` not taken by an earlier one, pixel (u, v) at depth
  // z(u, v) metres; `plane` -1 = on no plane. Returns its id.
  int Add(const Block& b, const std::function<double(int, int)>& z, const core::Vec3f& normal,
          PatchType type, int segment, int plane) {
    const int id = static_cast<int>(normal_.size());
    for (int v = b.v0; v < b.v1; ++v) {
      for (int u = b.u0; u < b.u1; ++u) {
        const size_t px = static_cast<size_t>(v) * w_ + u;
        if (sv_.pixel_label[px] >= 0) continue;
        const double d = z(u, v);
        cloud_.xyz[px] =
            core::Vec3f{static_cast<float>((u - k_.cx) * d / k_.fx),
                        static_cast<float>((v - k_.cy) * d / k_.fy), static_cast<float>(d)};
        sv_.pixel_label[px] = id;
      }
    }
    normal_.push_back(normal);
    type_.push_back(type);
    link_.segment.push_back(segment);
    planes_.patch_plane.push_back(plane);
    return id;
  }
  int Add(const Block& b, double z, const core::Vec3f& normal, PatchType type, int segment,
          int plane) {
    return Add(
        b, [z](int, int) { return z; }, normal, type, segment, plane);
  }

  void Connect(const std::vector<std::pair<int, int>>& edges) { edges_ = edges; }

  const core::CameraIntrinsics& intrinsics() const { return k_; }
  int width() const { return w_; }

  // The labels per pixel of the organized image after Refiner::Compute with `params`, run on
  // the organized cloud or on its valid points in a shuffled order (mapped back to pixels);
  // `objects` the object count.
  struct Run {
    std::vector<uint32_t> labels;
    size_t objects{0};
  };
  Run Refine(const ObjectParams& params, bool unorganized,
             const geometry::PlanarRegions* support_first = nullptr) {
    Finish();
    std::vector<size_t> order;
    for (size_t px = 0; px < cloud_.xyz.size(); ++px) {
      if (sv_.pixel_label[px] >= 0) order.push_back(px);
    }
    core::PointCloud cloud = cloud_;
    supervoxel::Supervoxels sv = sv_;
    if (unorganized) {
      std::mt19937 rng(7);
      std::shuffle(order.begin(), order.end(), rng);
      cloud.width = static_cast<int>(order.size());
      cloud.height = 1;
      cloud.xyz.clear();
      sv.pixel_label.clear();
      for (const size_t px : order) {
        cloud.xyz.push_back(cloud_.xyz[px]);
        sv.pixel_label.push_back(sv_.pixel_label[px]);
      }
      sv.width = cloud.width;
      sv.height = 1;
    }
    Refiner dut(params);
    SegmentationResult result;
    result.labels.Reset(cloud.width, cloud.height, 0u);
    dut.Compute(k_, cloud, sv, features_, link_, planes_, &result, support_first);
    Run run;
    run.objects = result.objects.size();
    if (!unorganized) {
      run.labels = result.labels.data;
    } else {
      run.labels.assign(cloud_.xyz.size(), 0u);
      for (size_t k = 0; k < order.size(); ++k) run.labels[order[k]] = result.labels.data[k];
    }
    return run;
  }

  // The one label of every pixel of `b`, or -1 when they differ.
  int64_t BlockLabel(const Run& run, const Block& b) const {
    const uint32_t first = run.labels[static_cast<size_t>(b.v0) * w_ + b.u0];
    for (int v = b.v0; v < b.v1; ++v) {
      for (int u = b.u0; u < b.u1; ++u) {
        if (run.labels[static_cast<size_t>(v) * w_ + u] != first) return -1;
      }
    }
    return first;
  }

 private:
  // Supervoxel statistics from the pixels, the features and the CSR adjacency.
  void Finish() {
    const size_t n = normal_.size();
    sv_.num_points.assign(n, 0);
    std::vector<std::array<double, 7>> sums(n, std::array<double, 7>{});
    for (size_t px = 0; px < cloud_.xyz.size(); ++px) {
      const int32_t s = sv_.pixel_label[px];
      if (s < 0) continue;
      const core::Vec3f& p = cloud_.xyz[px];
      auto& t = sums[s];
      t[0] += 1;
      t[1] += p.x;
      t[2] += p.y;
      t[3] += p.z;
      t[4] += double{p.x} * p.x;
      t[5] += double{p.y} * p.y;
      t[6] += double{p.z} * p.z;
    }
    sv_.centroid.resize(n);
    sv_.eigenvalues.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const auto& t = sums[i];
      sv_.num_points[i] = static_cast<uint32_t>(t[0]);
      const core::Vec3f c{static_cast<float>(t[1] / t[0]), static_cast<float>(t[2] / t[0]),
                          static_cast<float>(t[3] / t[0])};
      sv_.centroid[i] = c;
      // The rectangles face the camera: their covariance is nearly diagonal.
      std::array<float, 3> var = {static_cast<float>(t[4] / t[0] - double{c.x} * c.x),
                                  static_cast<float>(t[5] / t[0] - double{c.y} * c.y),
                                  static_cast<float>(t[6] / t[0] - double{c.z} * c.z)};
      std::sort(var.begin(), var.end(), std::greater<>());
      sv_.eigenvalues[i] = core::Vec3f{var[0], var[1], std::max(0.f, var[2])};
    }
    sv_.normal = normal_;
    sv_.curvature.assign(n, 0.f);
    features_.num_points = sv_.num_points;
    features_.centroid = sv_.centroid;
    features_.eigenvalues = sv_.eigenvalues;
    features_.normal = normal_;
    features_.type = type_;
    std::vector<std::vector<uint32_t>> nb(n);
    for (const auto& [a, b] : edges_) {
      nb[a].push_back(static_cast<uint32_t>(b));
      nb[b].push_back(static_cast<uint32_t>(a));
    }
    sv_.adjacency_offsets.assign(1, 0);
    sv_.adjacency.clear();
    for (auto& list : nb) {
      std::sort(list.begin(), list.end());
      sv_.adjacency.insert(sv_.adjacency.end(), list.begin(), list.end());
      sv_.adjacency_offsets.push_back(static_cast<uint32_t>(sv_.adjacency.size()));
    }
  }

  int w_, h_;
  core::CameraIntrinsics k_;
  core::PointCloud cloud_;
  supervoxel::Supervoxels sv_;
  graph::PatchFeatures features_;
  graph::LinkageResult link_;
  optimize::PlaneLabeling planes_;
  std::vector<core::Vec3f> normal_;
  std::vector<PatchType> type_;
  std::vector<std::pair<int, int>> edges_;
};

// Supports need 0.002 m^2 here (a 60 x 20 pixel table at 1 m covers 0.0044 m^2, a 60 x 10
// object face at 0.9 m 0.0018 m^2); the cues not under test are off.
ObjectParams TestParams() {
  ObjectParams p;
  p.support_min_area_m2 = 0.002f;
  p.support_release_fraction = 0.f;
  p.support_reclaim_passes = 0;
  p.merge_small_groups = false;
  return p;
}

core::Vec3f Tilted(double deg) {  // kFacing turned about the image's vertical by `deg`
  const double a = deg * 3.14159265358979 / 180.0;
  return core::Vec3f{static_cast<float>(-std::sin(a)), 0.f, static_cast<float>(-std::cos(a))};
}

// Two boxes side by side whose faces alpha-expansion put on one plane: the left box's front,
// the right box's face turned by `angle_deg`. Both planar, different initial segments.
struct PlanePieces {
  HandFrame frame{60, 30};
  Block left{0, 0, 30, 10}, right{30, 0, 60, 10}, table{0, 10, 60, 30};
  explicit PlanePieces(double angle_deg) {
    const int plane = frame.AddPlane(kFacing, 0.9f);
    const int t = frame.Add(table, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    const int a = frame.Add(left, 0.9, kFacing, PatchType::kPlanar, 1, plane);
    const int b = frame.Add(right, 0.9, Tilted(angle_deg), PatchType::kPlanar, 2, plane);
    frame.Connect({{t, a}, {t, b}, {a, b}});
  }
};

TEST(Refiner, PlanePiecesMergeOnlyWithSimilarNormals) {
  ObjectParams p = TestParams();
  ASSERT_EQ(p.plane_merge_max_pair_angle_deg, 60.f);
  PlanePieces perpendicular(90.0);
  HandFrame::Run r = perpendicular.frame.Refine(p, false);
  EXPECT_EQ(r.objects, 2u);
  const int64_t a = perpendicular.frame.BlockLabel(r, perpendicular.left);
  const int64_t b = perpendicular.frame.BlockLabel(r, perpendicular.right);
  EXPECT_GT(a, 0);
  EXPECT_GT(b, 0);
  EXPECT_NE(a, b);
  EXPECT_EQ(perpendicular.frame.BlockLabel(r, perpendicular.table), 0);
  // The paper's rule (180 = whenever both are planar): one object.
  p.plane_merge_max_pair_angle_deg = 180.f;
  r = perpendicular.frame.Refine(p, false);
  EXPECT_EQ(r.objects, 1u);
  EXPECT_EQ(perpendicular.frame.BlockLabel(r, perpendicular.left), 1);
  EXPECT_EQ(perpendicular.frame.BlockLabel(r, perpendicular.right), 1);
  // Pieces 30 degrees apart are one surface under the check too.
  p.plane_merge_max_pair_angle_deg = 60.f;
  PlanePieces similar(30.0);
  r = similar.frame.Refine(p, false);
  EXPECT_EQ(r.objects, 1u);
  EXPECT_EQ(similar.frame.BlockLabel(r, similar.right), 1);
}

// An object whose lowest rows alpha-expansion put on the table's plane: S (rows 10-13 under the
// object O) lies `height_m` above the table, in O's initial segment.
struct LowestRows {
  HandFrame frame{60, 30};
  Block object{20, 0, 40, 10}, low{20, 10, 40, 14};
  explicit LowestRows(double height_m) {
    const int o = frame.Add(object, 0.9, kFacing, PatchType::kPlanar, 1, -1);
    const int s = frame.Add(low, 1.0 - height_m, kFacing, PatchType::kPlanar, 1, 0);
    const int t1 = frame.Add({0, 10, 20, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    const int t2 = frame.Add({40, 10, 60, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    const int t3 = frame.Add({20, 14, 40, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    frame.Connect({{o, s}, {o, t1}, {o, t2}, {s, t1}, {s, t2}, {s, t3}, {t1, t3}, {t2, t3}});
  }
};

TEST(Refiner, SupportSupervoxelsAboveThePlaneAreReleased) {
  for (const bool unorganized : {false, true}) {
    SCOPED_TRACE(unorganized ? "unorganized" : "organized");
    LowestRows scene(0.01);
    ObjectParams p = TestParams();
    p.support_release_fraction = 0.5f;
    HandFrame::Run r = scene.frame.Refine(p, unorganized);
    EXPECT_EQ(r.objects, 1u);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.object), 1);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.low), 1);
    // Off: the rows stay table, as before.
    p.support_release_fraction = 0.f;
    r = scene.frame.Refine(p, unorganized);
    EXPECT_EQ(r.objects, 1u);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.object), 1);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.low), 0);
    // 3 mm above is within above_support_distance_m (4 mm): not above, not released.
    LowestRows flat(0.003);
    p.support_release_fraction = 0.5f;
    r = flat.frame.Refine(p, unorganized);
    EXPECT_EQ(flat.frame.BlockLabel(r, flat.low), 0);
  }
}

// A table piece off the fitted plane by `height_m`, touching no object: released, it is an
// object of its own only when it stands support_release_min_height_m (8 mm) above the table.
struct LoosePiece {
  HandFrame frame{60, 30};
  Block piece{40, 15, 50, 25};
  explicit LoosePiece(double height_m) {
    const int s = frame.Add(piece, 1.0 - height_m, kFacing, PatchType::kPlanar, 1, 0);
    const int t = frame.Add({0, 0, 60, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    frame.Connect({{s, t}});
  }
};

TEST(Refiner, AGroupOfReleasedSupervoxelsAloneMustStandClearlyAbove) {
  ObjectParams p = TestParams();
  p.min_object_points = 50;
  p.support_release_fraction = 0.5f;
  ASSERT_EQ(p.support_release_min_height_m, 0.008f);
  for (const bool unorganized : {false, true}) {
    SCOPED_TRACE(unorganized ? "unorganized" : "organized");
    LoosePiece low(0.005), high(0.012);
    // 5 mm: released, but too low on its own: background.
    HandFrame::Run r = low.frame.Refine(p, unorganized);
    EXPECT_EQ(r.objects, 0u);
    EXPECT_EQ(low.frame.BlockLabel(r, low.piece), 0);
    // 12 mm: an object.
    r = high.frame.Refine(p, unorganized);
    EXPECT_EQ(r.objects, 1u);
    EXPECT_EQ(high.frame.BlockLabel(r, high.piece), 1);
    // Without the rule every released group stays.
    ObjectParams any = p;
    any.support_release_min_height_m = 0.f;
    r = low.frame.Refine(any, unorganized);
    EXPECT_EQ(r.objects, 1u);
    EXPECT_EQ(low.frame.BlockLabel(r, low.piece), 1);
  }
}

// A piece of the table 2 mm above its fitted plane that the plane labelling gave a plane of
// its own (or none), touching only the table: it lies flat on the support. One 12 mm above
// it does not.
struct FlatPiece {
  HandFrame frame{60, 30};
  Block piece{40, 15, 50, 25};
  FlatPiece(double height_m, bool own_plane) {
    const int plane = own_plane ? frame.AddPlane(kFacing, static_cast<float>(1.0 - height_m)) : -1;
    const int s = frame.Add(piece, 1.0 - height_m, kFacing,
                            own_plane ? PatchType::kPlanar : PatchType::kNonPlanar, 1, plane);
    const int t = frame.Add({0, 0, 60, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    frame.Connect({{s, t}});
  }
};

// `piece` of `frame` is support at `p`, and an object of its own with support_flat_groups off
// (the paper's pipeline).
void ExpectSupportOnlyWithFlatGroups(HandFrame& frame, const Block& piece, const ObjectParams& p,
                                     bool unorganized) {
  HandFrame::Run r = frame.Refine(p, unorganized);
  EXPECT_EQ(r.objects, 0u);
  EXPECT_EQ(frame.BlockLabel(r, piece), 0);
  ObjectParams off = p;
  off.support_flat_groups = false;
  r = frame.Refine(off, unorganized);
  EXPECT_EQ(r.objects, 1u);
  EXPECT_EQ(frame.BlockLabel(r, piece), 1);
}

TEST(Refiner, AGroupLyingFlatOnTheSupportIsTheSupport) {
  ObjectParams p = TestParams();
  p.min_object_points = 50;
  ASSERT_TRUE(p.support_flat_groups);
  ASSERT_EQ(p.above_support_distance_m, 0.004f);
  for (const bool unorganized : {false, true}) {
    for (const bool own_plane : {false, true}) {
      SCOPED_TRACE(std::string(unorganized ? "unorganized" : "organized") +
                   (own_plane ? ", own plane" : ", no plane"));
      FlatPiece flat(0.002, own_plane), high(0.012, own_plane);
      ExpectSupportOnlyWithFlatGroups(flat.frame, flat.piece, p, unorganized);
      const HandFrame::Run r = high.frame.Refine(p, unorganized);
      EXPECT_EQ(r.objects, 1u);
      EXPECT_EQ(high.frame.BlockLabel(r, high.piece), 1);
    }
  }
}

// The table's front edge seen from above: two supervoxels of one initial segment, 1 mm and
// 8 mm below the table's plane (their centroid 4.5 mm below, within below_support_margin_m),
// on no plane. Nothing of it stands above the table: it is support too.
struct FrontEdge {
  HandFrame frame{60, 30};
  Block upper{10, 20, 50, 25}, lower{10, 25, 50, 30};
  FrontEdge() {
    const int a = frame.Add(upper, 1.001, kFacing, PatchType::kNonPlanar, 1, -1);
    const int b = frame.Add(lower, 1.008, kFacing, PatchType::kNonPlanar, 1, -1);
    const int t = frame.Add({0, 0, 60, 20}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    frame.Connect({{a, b}, {a, t}});
  }
};

TEST(Refiner, AGroupStandingNowhereAboveTheSupportIsTheSupport) {
  ObjectParams p = TestParams();
  p.min_object_points = 50;
  ASSERT_EQ(p.below_support_margin_m, 0.005f);
  for (const bool unorganized : {false, true}) {
    SCOPED_TRACE(unorganized ? "unorganized" : "organized");
    FrontEdge edge;
    ExpectSupportOnlyWithFlatGroups(edge.frame, edge.lower, p, unorganized);
  }
}

// An object O (rows 0-9, 5 cm above the table) with the ring of table the support-first step
// left around it (rows 10-19, support supervoxel T) and, in that ring, a piece P 5 mm above the
// plane (released, too low to stand alone). Rows 20-29 hold no point: in the organized frame
// they are either missing or taken by the support-first step.
struct Ring {
  HandFrame frame{60, 30};
  Block object{20, 0, 40, 10}, piece{25, 10, 35, 14};
  geometry::PlanarRegions taken;
  Ring() {
    const int o = frame.Add(object, 0.95, kFacing, PatchType::kPlanar, 1, -1);
    const int s = frame.Add(piece, 0.995, kFacing, PatchType::kPlanar, 0, 0);
    const int t = frame.Add({0, 10, 60, 20}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    frame.Connect({{o, s}, {o, t}, {s, t}});
    taken.taken_words_per_row = 1;
    taken.taken_bits.assign(30, 0);
    for (int v = 20; v < 30; ++v) taken.taken_bits[v] = (uint64_t{1} << 60) - 1;
  }
};

TEST(Refiner, APieceOfTheSupportNextToWhatTheSupportFirstStepTookIsNotWalledIn) {
  ObjectParams p = TestParams();
  p.min_object_points = 20;
  p.support_release_fraction = 0.5f;
  ASSERT_GT(p.support_release_enclosed_max_area_m2, 0.f);
  Ring scene;
  ASSERT_TRUE(scene.taken.Taken(0, 20));
  ASSERT_FALSE(scene.taken.Taken(0, 19));
  ASSERT_FALSE(scene.taken.Taken(60, 20));  // beyond the row's pixels
  // The ring alone is a small piece of support touching the object: walled in, as the bottom
  // inside a pot, so the low piece stays an object.
  HandFrame::Run r = scene.frame.Refine(p, false);
  EXPECT_EQ(r.objects, 2u);
  EXPECT_NE(scene.frame.BlockLabel(r, scene.piece), 0);
  // Next to the taken pixels the ring is the rest of the table: the piece is background.
  r = scene.frame.Refine(p, false, &scene.taken);
  EXPECT_EQ(r.objects, 1u);
  EXPECT_EQ(scene.frame.BlockLabel(r, scene.object), 1);
  EXPECT_EQ(scene.frame.BlockLabel(r, scene.piece), 0);
}

// An object O (rows 0-9) standing on a support supervoxel S (rows 10-17) whose top two rows
// lie 1 cm above the table (25 % of S: not released): the object's bottom that the
// supervoxel took. Columns 20-24 of those rows lie 5 cm above instead (a depth step).
struct ObjectBottom {
  HandFrame frame{60, 30};
  Block object{20, 0, 40, 10}, bottom{25, 10, 40, 12}, first_row{25, 10, 40, 11},
      second_row{25, 11, 40, 12}, step{20, 10, 25, 12}, rest{20, 12, 40, 18};
  ObjectBottom() {
    const int o = frame.Add(object, 0.99, kFacing, PatchType::kPlanar, 1, -1);
    auto z = [](int u, int v) { return v >= 12 ? 1.0 : u < 25 ? 0.95 : 0.99; };
    const int s = frame.Add({20, 10, 40, 18}, z, kFacing, PatchType::kPlanar, 0, 0);
    const int t1 = frame.Add({0, 0, 20, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    const int t2 = frame.Add({40, 0, 60, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    const int t3 = frame.Add({20, 18, 40, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    frame.Connect({{o, s}, {o, t1}, {o, t2}, {s, t1}, {s, t2}, {s, t3}, {t1, t3}, {t2, t3}});
  }
};

TEST(Refiner, PointsAboveTheSupportNextToAnObjectAreReclaimed) {
  ObjectBottom scene;
  ObjectParams p = TestParams();
  p.support_release_fraction = 0.5f;
  ASSERT_EQ(p.support_reclaim_passes, 0);
  for (const bool unorganized : {false, true}) {
    SCOPED_TRACE(unorganized ? "unorganized" : "organized");
    // Off: the object ends at row 9.
    p.support_reclaim_passes = 0;
    HandFrame::Run r = scene.frame.Refine(p, unorganized);
    ASSERT_EQ(r.objects, 1u);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.object), 1);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.bottom), 0);
    // On: the raised rows join it; not across the 4 cm step, not the points on the table.
    p.support_reclaim_passes = 8;
    r = scene.frame.Refine(p, unorganized);
    ASSERT_EQ(r.objects, 1u);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.object), 1);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.bottom), 1);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.step), 0);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.rest), 0);
  }
  // One pass reaches one pixel into the support (organized: the 4-neighbours).
  p.support_reclaim_passes = 1;
  const HandFrame::Run r = scene.frame.Refine(p, false);
  EXPECT_EQ(scene.frame.BlockLabel(r, scene.first_row), 1);
  EXPECT_EQ(scene.frame.BlockLabel(r, scene.second_row), 0);
}

// Two objects G (300 points) and H (240) with a small group between them (three supervoxels,
// 60 points in all, its own initial segment) that touches H through three adjacencies and G
// through `g_edges`; and a small isolated group I on the table.
struct SmallGroups {
  HandFrame frame{60, 30};
  Block g{0, 0, 30, 10}, h{36, 0, 60, 10}, small{30, 0, 36, 10}, island{50, 20, 56, 26};
  explicit SmallGroups(int g_edges) {
    const int gi = frame.Add(g, 0.9, kFacing, PatchType::kPlanar, 1, -1);
    const int s1 = frame.Add({30, 0, 36, 4}, 0.9, kFacing, PatchType::kPlanar, 2, -1);
    const int s2 = frame.Add({30, 4, 36, 7}, 0.9, kFacing, PatchType::kPlanar, 2, -1);
    const int s3 = frame.Add({30, 7, 36, 10}, 0.9, kFacing, PatchType::kPlanar, 2, -1);
    const int hi = frame.Add(h, 0.9, kFacing, PatchType::kPlanar, 3, -1);
    const int ii = frame.Add(island, 0.9, kFacing, PatchType::kPlanar, 4, -1);
    const int t = frame.Add({0, 10, 60, 30}, 1.0, kFacing, PatchType::kPlanar, 0, 0);
    std::vector<std::pair<int, int>> edges = {{s1, s2}, {s2, s3}, {s1, hi}, {s2, hi}, {s3, hi},
                                              {t, gi},  {t, hi},  {t, s3},  {t, ii}};
    const int small_ids[] = {s1, s2, s3};
    for (int k = 0; k < g_edges; ++k) edges.emplace_back(gi, small_ids[k]);
    frame.Connect(edges);
  }
};

TEST(Refiner, SmallGroupsJoinTheirMostConnectedNeighbour) {
  ObjectParams p = TestParams();
  ASSERT_EQ(p.min_object_points, 150);
  for (const bool unorganized : {false, true}) {
    SCOPED_TRACE(unorganized ? "unorganized" : "organized");
    SmallGroups scene(1);
    // Off: the small group and the island are dropped.
    HandFrame::Run r = scene.frame.Refine(p, unorganized);
    EXPECT_EQ(r.objects, 2u);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.small), 0);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.island), 0);
    const int64_t g_off = scene.frame.BlockLabel(r, scene.g);
    const int64_t h_off = scene.frame.BlockLabel(r, scene.h);
    EXPECT_GT(g_off, 0);
    EXPECT_GT(h_off, 0);
    EXPECT_NE(g_off, h_off);
    // On: it joins H (3 adjacencies against G's 1) although G is larger; the island, with no
    // foreground neighbour, is still dropped.
    p.merge_small_groups = true;
    r = scene.frame.Refine(p, unorganized);
    EXPECT_EQ(r.objects, 2u);
    const int64_t h_on = scene.frame.BlockLabel(r, scene.h);
    EXPECT_GT(h_on, 0);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.small), h_on);
    EXPECT_NE(scene.frame.BlockLabel(r, scene.g), h_on);
    EXPECT_EQ(scene.frame.BlockLabel(r, scene.island), 0);
    // A tie (3 and 3): the larger neighbour, G.
    SmallGroups tie(3);
    r = tie.frame.Refine(p, unorganized);
    EXPECT_EQ(r.objects, 2u);
    EXPECT_EQ(tie.frame.BlockLabel(r, tie.small), tie.frame.BlockLabel(r, tie.g));
    p.merge_small_groups = false;
  }
}

}  // namespace
}  // namespace clutterseg::pipeline
