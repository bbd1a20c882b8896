// PartitionPrior: a merge or split of still objects is published only after hold_frames
// frames in a row; anything that moved, and the first frames after a change, pass at once.
// Objects by arrival: surfaces put down at different times are different objects; a pushed
// object stays whole.
#include "clutterseg/pipeline/partition_prior.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <utility>

#include <gtest/gtest.h>

#include "clutterseg/core/label_scan.h"
#include "clutterseg/core/thread_pool.h"

namespace clutterseg::pipeline {
namespace {

constexpr int kW = 80, kH = 60;

// Two boxes side by side at 0.9 m in front of a wall at 1.0 m: A is columns 10-29, B 30-49,
// rows 10-39. `b_depth` moves B.
core::PointCloud Scene(float a_depth = 0.9f, float b_depth = 0.9f) {
  core::PointCloud c;
  c.width = kW;
  c.height = kH;
  c.xyz.resize(static_cast<size_t>(kW * kH));
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      float z = 1.0f;
      if (v >= 10 && v < 40 && u >= 10 && u < 30) z = a_depth;
      if (v >= 10 && v < 40 && u >= 30 && u < 50) z = b_depth;
      c.xyz[static_cast<size_t>(v * kW + u)] =
          core::Vec3f{(u - 40) * 0.002f * z, (v - 30) * 0.002f * z, z};
    }
  }
  return c;
}

// A segmentation whose label at (u, v) is label(u, v), with objects 1..n.
SegmentationResult Segmentation(const std::function<uint32_t(int, int)>& label) {
  SegmentationResult r;
  r.width = kW;
  r.height = kH;
  r.labels.width = kW;
  r.labels.height = kH;
  r.labels.data.resize(static_cast<size_t>(kW * kH));
  uint32_t n = 0;
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      const uint32_t l = label(u, v);
      r.labels.data[static_cast<size_t>(v * kW + u)] = l;
      n = std::max(n, l);
    }
  }
  r.objects.assign(n, Object{});
  for (uint32_t k = 0; k < n; ++k) r.objects[k].id = k + 1;
  return r;
}

bool InBoxes(int u, int v) { return v >= 10 && v < 40 && u >= 10 && u < 50; }
SegmentationResult Split() {
  return Segmentation([](int u, int v) { return InBoxes(u, v) ? (u < 30 ? 1u : 2u) : 0u; });
}
SegmentationResult Merged() {
  return Segmentation([](int u, int v) { return InBoxes(u, v) ? 1u : 0u; });
}
uint32_t At(const SegmentationResult& r, int u, int v) {
  return r.labels.data[static_cast<size_t>(v * kW + u)];
}

// One frame through a prior and through the same prior with a rule off, each on its own copy
// of the segmentation: {with the rule, without}.
std::pair<SegmentationResult, SegmentationResult> ApplyBoth(PartitionPrior* prior,
                                                            PartitionPrior* without,
                                                            const core::PointCloud& cloud,
                                                            int64_t seq,
                                                            const SegmentationResult& segmented) {
  SegmentationResult r = segmented, w = segmented;
  prior->Apply(cloud, seq, &r);
  without->Apply(cloud, seq, &w);
  return {std::move(r), std::move(w)};
}

PartitionPriorParams Hold(int frames) {
  PartitionPriorParams p;
  p.hold_frames = frames;
  p.arrival_gap_frames = 0;  // the hysteresis alone
  return p;
}

// The defaults: the objects by arrival on, gap 10 frames.
PartitionPriorParams Arrival() {
  PartitionPriorParams p;
  p.arrival_gap_frames = 10;
  return p;
}

// A scene of depth(u, v) (metres) on the same grid.
core::PointCloud SceneOf(const std::function<float(int, int)>& depth) {
  core::PointCloud c = Scene();
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      const float z = depth(u, v);
      c.xyz[static_cast<size_t>(v * kW + u)] =
          core::Vec3f{(u - 40) * 0.002f * z, (v - 30) * 0.002f * z, z};
    }
  }
  return c;
}

// Frames 1..4 of the two boxes segmented apart: the partition is established.
void Establish(PartitionPrior* prior, const core::PointCloud& cloud, bool split = true) {
  for (int64_t seq = 1; seq <= 4; ++seq) {
    SegmentationResult r = split ? Split() : Merged();
    EXPECT_FALSE(prior->Apply(cloud, seq, &r)) << seq;
  }
}

TEST(PartitionPrior, AMergeOfStillObjectsIsPublishedAfterHoldFramesInARow) {
  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  Establish(&prior, cloud);
  for (int64_t seq = 5; seq <= 6; ++seq) {
    SegmentationResult r = Merged();
    EXPECT_TRUE(prior.Apply(cloud, seq, &r)) << seq;
    EXPECT_EQ(prior.counts().held_merges, 1);
    ASSERT_EQ(r.objects.size(), 2u) << seq;  // cut back along the previous boundary
    EXPECT_NE(At(r, 20, 20), At(r, 40, 20));
    EXPECT_NE(At(r, 20, 20), 0u);
    EXPECT_NE(At(r, 40, 20), 0u);
    EXPECT_EQ(r.objects[0].num_points + r.objects[1].num_points, 40u * 30u);
    EXPECT_EQ(r.objects[At(r, 20, 20) - 1].num_points, 20u * 30u);
  }
  SegmentationResult third = Merged();
  EXPECT_FALSE(prior.Apply(cloud, 7, &third));  // the third merged frame in a row
  EXPECT_EQ(prior.counts().passed_merges, 1);
  EXPECT_EQ(third.objects.size(), 1u);
}

TEST(PartitionPrior, AMergeIsHeldTheSameWayInTwoHalves) {
  PartitionPrior whole(Hold(3), TemporalFilterParams{}), halves(Hold(3), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  int held = 0, passed = 0;
  for (int64_t seq = 1; seq <= 8; ++seq) {
    SegmentationResult a = seq <= 4 ? Split() : Merged(), b = a;
    const bool changed = whole.Apply(cloud, seq, &a);
    EXPECT_EQ(halves.Relabel(cloud, seq, &b), changed) << seq;
    halves.Remember();
    EXPECT_EQ(b.labels.data, a.labels.data) << seq;
    EXPECT_EQ(halves.counts().held_merges, whole.counts().held_merges) << seq;
    EXPECT_EQ(halves.counts().passed_merges, whole.counts().passed_merges) << seq;
    held += whole.counts().held_merges;
    passed += whole.counts().passed_merges;
  }
  EXPECT_EQ(held, 2);  // held twice, then published
  EXPECT_EQ(passed, 1);
}

TEST(PartitionPriorDeathTest, RelabelWithoutRememberIsAProgrammingError) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  SegmentationResult r = Split();
  prior.Relabel(cloud, 1, &r);
  SegmentationResult again = Split();
  EXPECT_DEATH(prior.Relabel(cloud, 2, &again), "pending_result_");
}

TEST(PartitionPrior, AMergeSeenNowAndThenIsNeverPublished) {
  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  Establish(&prior, cloud);
  for (int64_t seq = 5; seq <= 20; ++seq) {
    SegmentationResult r = seq % 3 == 0 ? Split() : Merged();  // merged two frames in three
    prior.Apply(cloud, seq, &r);
    EXPECT_EQ(r.objects.size(), 2u) << seq;
  }
}

TEST(PartitionPrior, ASplitOfAStillObjectIsHeldTheSameWay) {
  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  Establish(&prior, cloud, /*split=*/false);
  for (int64_t seq = 5; seq <= 6; ++seq) {
    SegmentationResult r = Split();
    EXPECT_TRUE(prior.Apply(cloud, seq, &r)) << seq;
    EXPECT_EQ(prior.counts().held_splits, 1);
    ASSERT_EQ(r.objects.size(), 1u);
    EXPECT_EQ(r.objects[0].num_points, 40u * 30u);
    EXPECT_EQ(At(r, 20, 20), At(r, 40, 20));
  }
  SegmentationResult third = Split();
  EXPECT_FALSE(prior.Apply(cloud, 7, &third));
  EXPECT_EQ(third.objects.size(), 2u);
}

// Box A cut in two by the segmentation, its right part (columns 18-29) merged with box B: the
// held merge cuts that part back to A, and it joins A's left part (its own segment now), so A
// is published whole, as before; without the rule A is two pieces.
TEST(PartitionPrior, AnObjectCutInTwoWithOnePartMergedIsPublishedWhole) {
  PartitionPriorParams without_rule = Hold(3);
  without_rule.cut_piece_joins_rest = false;
  PartitionPrior prior(Hold(3), TemporalFilterParams{}),
      without(without_rule, TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  Establish(&prior, cloud);
  Establish(&without, cloud);
  const SegmentationResult cut =
      Segmentation([](int u, int v) { return InBoxes(u, v) ? (u < 18 ? 1u : 2u) : 0u; });
  for (int64_t seq = 5; seq <= 6; ++seq) {
    const auto [r, w] = ApplyBoth(&prior, &without, cloud, seq, cut);
    EXPECT_EQ(prior.counts().held_merges, 1) << seq;
    ASSERT_EQ(r.objects.size(), 2u) << seq;
    EXPECT_EQ(At(r, 12, 20), At(r, 25, 20)) << seq;  // A whole
    EXPECT_NE(At(r, 25, 20), At(r, 40, 20)) << seq;
    EXPECT_EQ(r.objects[At(r, 12, 20) - 1].num_points, 20u * 30u) << seq;
    ASSERT_EQ(w.objects.size(), 3u) << seq;  // A in two pieces
    EXPECT_NE(At(w, 12, 20), At(w, 25, 20)) << seq;
  }
  // The third frame in a row publishes the segmentation's partition (the merge has lasted).
  SegmentationResult third = cut;
  prior.Apply(cloud, 7, &third);
  EXPECT_EQ(third.objects.size(), 2u);
  EXPECT_EQ(At(third, 25, 20), At(third, 40, 20));
}

TEST(PartitionPrior, WhatMovedIsPublishedInTheFrameOfTheChange) {
  PartitionPrior prior(Hold(5), TemporalFilterParams{});
  Establish(&prior, Scene());
  // B pushed 3 cm towards the camera as it is merged with A: not still, published as is.
  SegmentationResult r = Merged();
  EXPECT_FALSE(prior.Apply(Scene(0.9f, 0.87f), 5, &r));
  EXPECT_EQ(r.objects.size(), 1u);
  EXPECT_EQ(prior.counts().held_merges, 0);
}

TEST(PartitionPrior, APartitionMadeInTheFrameOfAChangeIsNotHeld) {
  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  Establish(&prior, Scene());
  // Something passes in front of both boxes (frame 5) and leaves (frame 6): for the next
  // hold_frames frames the boxes' partition is new, and whatever the segmentation says passes.
  SegmentationResult passing = Merged();
  EXPECT_FALSE(prior.Apply(Scene(0.5f, 0.5f), 5, &passing));
  SegmentationResult back = Split();
  EXPECT_FALSE(prior.Apply(Scene(), 6, &back));
  EXPECT_EQ(back.objects.size(), 2u);
  SegmentationResult merged = Merged();
  EXPECT_FALSE(prior.Apply(Scene(), 7, &merged));
  EXPECT_EQ(merged.objects.size(), 1u);
}

TEST(PartitionPrior, PixelsOfNeitherPartGoToTheNearestPart) {
  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  Establish(&prior, cloud);
  // The merged segment also takes a strip of the wall right of B (columns 50-54).
  SegmentationResult r =
      Segmentation([](int u, int v) { return v >= 10 && v < 40 && u >= 10 && u < 55 ? 1u : 0u; });
  EXPECT_TRUE(prior.Apply(cloud, 5, &r));
  ASSERT_EQ(r.objects.size(), 2u);
  EXPECT_EQ(At(r, 52, 20), At(r, 40, 20));
  EXPECT_NE(At(r, 52, 20), At(r, 20, 20));
}

TEST(PartitionPrior, OffUnorganizedOrARestartedStreamChangesNothing) {
  const core::PointCloud cloud = Scene();
  PartitionPrior off(Hold(1), TemporalFilterParams{});
  Establish(&off, cloud);
  SegmentationResult merged = Merged();
  EXPECT_FALSE(off.Apply(cloud, 5, &merged));
  EXPECT_EQ(merged.objects.size(), 1u);

  PartitionPrior restarted(Hold(3), TemporalFilterParams{});
  Establish(&restarted, cloud);
  SegmentationResult again = Merged();
  EXPECT_FALSE(restarted.Apply(cloud, 1, &again));  // the sequence starts over: no history
  EXPECT_EQ(again.objects.size(), 1u);

  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  core::PointCloud flat = cloud;
  flat.width = kW * kH;
  flat.height = 1;
  SegmentationResult r = Split();
  r.labels.width = kW * kH;
  r.labels.height = 1;
  EXPECT_FALSE(prior.Apply(flat, 1, &r));
  EXPECT_EQ(prior.memory_bytes(), 0u);
}

TEST(PartitionPrior, ARecomputedFrameKeepsTheSegmentersObjectsTime) {
  PartitionPrior prior(Hold(3), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  Establish(&prior, cloud);
  SegmentationResult r = Merged();
  r.times[Stage::kObjects] = 1234.5;
  ASSERT_TRUE(prior.Apply(cloud, 5, &r));
  EXPECT_EQ(r.times[Stage::kObjects], 1234.5);
}

// ---- Objects by arrival --------------------------------------------------------------------

// Box A (columns 10-29) stands from the first frame; box B (columns 30-49) is set flush beside
// it at frame 30: the same depth, no boundary in any single frame, and the segmentation joins
// them. From the frame B is confirmed (arrival_confirm_frames) on, they are two objects.
TEST(PartitionPrior, ABoxSetFlushOnAnotherIsAnotherObject) {
  const PartitionPriorParams defaults = Arrival();
  PartitionPrior prior(defaults, TemporalFilterParams{});
  const core::PointCloud a_only = Scene(0.9f, 1.0f), both = Scene();
  const SegmentationResult a =
      Segmentation([](int u, int v) { return v >= 10 && v < 40 && u >= 10 && u < 30 ? 1u : 0u; });
  for (int64_t seq = 1; seq < 30; ++seq) {
    SegmentationResult r = a;
    prior.Apply(a_only, seq, &r);
    EXPECT_EQ(r.objects.size(), 1u) << seq;
  }
  // B is confirmed in its arrival_confirm_frames-th frame; the hysteresis then holds the
  // partition the still scene had (A and B joined) for hold_frames - 1 frames more.
  const int64_t confirmed = 30 + defaults.arrival_confirm_frames - 1;
  const int64_t published = confirmed + defaults.hold_frames - 1;
  for (int64_t seq = 30; seq < 60; ++seq) {
    SegmentationResult r = Merged();
    prior.Apply(both, seq, &r);
    if (seq < confirmed) {
      EXPECT_EQ(r.objects.size(), 1u) << seq;  // as segmented
    }
    if (seq < published) continue;
    ASSERT_EQ(r.objects.size(), 2u) << seq;
    EXPECT_NE(At(r, 20, 20), At(r, 40, 20)) << seq;
    EXPECT_EQ(At(r, 11, 11), At(r, 28, 38)) << seq;
    EXPECT_EQ(At(r, 31, 11), At(r, 48, 38)) << seq;
    EXPECT_EQ(r.objects[At(r, 20, 20) - 1].num_points, 20u * 30u) << seq;
  }
  // Something passes in front of both for six frames and leaves: the surfaces come back with
  // their arrivals, and the boxes stay two.
  for (int64_t seq = 60; seq < 66; ++seq) {
    SegmentationResult r = Merged();
    prior.Apply(Scene(0.5f, 0.5f), seq, &r);
  }
  for (int64_t seq = 66; seq < 72; ++seq) {
    SegmentationResult r = Merged();
    prior.Apply(both, seq, &r);
    ASSERT_EQ(r.objects.size(), 2u) << seq;
    EXPECT_NE(At(r, 20, 20), At(r, 40, 20)) << seq;
  }
  // A hand over the whole view for eight frames, long enough to be confirmed as the surface
  // (every pixel changes: the history steps its candidates in its vectorised pass), and taken
  // away: the boxes come back with their arrivals.
  const core::PointCloud hand = SceneOf([](int, int) { return 0.3f; });
  for (int64_t seq = 72; seq < 80; ++seq) {
    SegmentationResult r = Segmentation([](int, int) { return 0u; });
    prior.Apply(hand, seq, &r);
  }
  for (int64_t seq = 80; seq < 86; ++seq) {
    SegmentationResult r = Merged();
    prior.Apply(both, seq, &r);
    ASSERT_EQ(r.objects.size(), 2u) << seq;
    EXPECT_NE(At(r, 20, 20), At(r, 40, 20)) << seq;
  }
  // Off: one object throughout.
  PartitionPriorParams off = defaults;
  off.arrival_gap_frames = 0;
  PartitionPrior without(off, TemporalFilterParams{});
  for (int64_t seq = 1; seq < 60; ++seq) {
    SegmentationResult r = seq < 30 ? a : Merged();
    without.Apply(seq < 30 ? a_only : both, seq, &r);
    EXPECT_EQ(r.objects.size(), 1u) << seq;
  }
}

// Objects there from the first frame have no arrival to tell them apart or together: two
// boxes joined by the segmentation stay joined, two it separates stay separate.
TEST(PartitionPrior, ObjectsThereFromTheStartAreLeftAsSegmented) {
  PartitionPrior joined(Arrival(), TemporalFilterParams{});
  PartitionPrior apart(Arrival(), TemporalFilterParams{});
  const core::PointCloud cloud = Scene();
  for (int64_t seq = 1; seq < 60; ++seq) {
    SegmentationResult merged = Merged(), split = Split();
    EXPECT_FALSE(joined.Apply(cloud, seq, &merged)) << seq;
    EXPECT_FALSE(apart.Apply(cloud, seq, &split)) << seq;
    EXPECT_EQ(merged.objects.size(), 1u);
    EXPECT_EQ(split.objects.size(), 2u);
  }
}

// Box A (columns 10-49) stands from the first frame and is pushed 4 columns to the right at
// frame 30. Most of its pixels keep their depth, the leading columns arrive in front of the
// wall and the trailing ones uncover it: it moved, and stays one object.
TEST(PartitionPrior, APushedObjectStaysWhole) {
  PartitionPrior prior(Arrival(), TemporalFilterParams{});
  const auto box_at = [](int left) {
    return [left](int u, int v) {
      return v >= 10 && v < 40 && u >= left && u < left + 40 ? 0.9f : 1.0f;
    };
  };
  const auto segment_at = [](int left) {
    return Segmentation(
        [left](int u, int v) { return v >= 10 && v < 40 && u >= left && u < left + 40 ? 1u : 0u; });
  };
  // Without the move (it needs more uncovered pixels than there are) the pushed box would be
  // cut into its old part and its leading columns.
  PartitionPriorParams blind = Arrival();
  blind.arrival_moved_min_pixels = 1 << 20;
  PartitionPrior without(blind, TemporalFilterParams{});
  bool moved = false, cut_without = false;
  for (int64_t seq = 1; seq < 60; ++seq) {
    const int left = seq < 30 ? 10 : 14;
    const auto [r, w] = ApplyBoth(&prior, &without, SceneOf(box_at(left)), seq, segment_at(left));
    moved = moved || prior.counts().arrival_moves > 0;
    cut_without = cut_without || w.objects.size() > 1;
    ASSERT_EQ(r.objects.size(), 1u) << seq;
    EXPECT_EQ(std::count(r.labels.data.begin(), r.labels.data.end(), 1u), 40 * 30) << seq;
  }
  EXPECT_TRUE(moved);
  EXPECT_TRUE(cut_without);
}

// A can lying down is put in front of the wall at frame 30: its lowest rows stay within the
// depth band of the wall behind them (the wall's surface, never in a segment until the can
// came) and its others come closer. The wall's arrival does not cut the can.
TEST(PartitionPrior, AnObjectPartlyWithinTheBandOfTheBackgroundIsNotCutFromIt) {
  PartitionPrior prior(Arrival(), TemporalFilterParams{});
  const core::PointCloud wall = SceneOf([](int, int) { return 1.0f; });
  const core::PointCloud can = SceneOf([](int u, int v) {
    if (v < 10 || v >= 40 || u < 20 || u >= 50) return 1.0f;
    return v < 32 ? 0.9f : 0.998f;  // 2 mm: within the 7 mm band at 1 m
  });
  const SegmentationResult none = Segmentation([](int, int) { return 0u; });
  const SegmentationResult one =
      Segmentation([](int u, int v) { return v >= 10 && v < 40 && u >= 20 && u < 50 ? 1u : 0u; });
  for (int64_t seq = 1; seq < 80; ++seq) {
    SegmentationResult r = seq < 30 ? none : one;
    prior.Apply(seq < 30 ? wall : can, seq, &r);
    if (seq < 30) continue;
    ASSERT_EQ(r.objects.size(), 1u) << seq;
    EXPECT_EQ(std::count(r.labels.data.begin(), r.labels.data.end(), 1u), 30 * 30) << seq;
  }
}

// The support-first step takes plane points out of the cloud the segments are made of, more
// or fewer from frame to frame; the surface history reads the scene's depth instead. Box A,
// there from the first frame, has its left half missing from the cloud for 20 frames: read
// from the cloud, that half would arrive at frame 20 and be cut off.
TEST(PartitionPrior, TheSurfacesAreFollowedInTheSceneDepthNotTheSegmentedCloud) {
  PartitionPrior scene(Arrival(), TemporalFilterParams{});
  PartitionPrior cloud_only(Arrival(), TemporalFilterParams{});
  const core::PointCloud full = Scene(0.9f, 1.0f);
  core::PointCloud holes = full;
  for (int v = 10; v < 40; ++v) {
    for (int u = 10; u < 20; ++u) holes.xyz[static_cast<size_t>(v * kW + u)].z = NAN;
  }
  std::vector<float> scene_z(full.size());
  for (size_t i = 0; i < full.size(); ++i) scene_z[i] = full.xyz[i].z;
  const SegmentationResult a =
      Segmentation([](int u, int v) { return v >= 10 && v < 40 && u >= 10 && u < 30 ? 1u : 0u; });
  bool cut = false;
  for (int64_t seq = 1; seq < 60; ++seq) {
    const core::PointCloud& cloud = seq < 20 ? holes : full;
    SegmentationResult r = a, c = a;
    scene.Apply(cloud, seq, &r, scene_z);
    cloud_only.Apply(cloud, seq, &c);
    ASSERT_EQ(r.objects.size(), 1u) << seq;
    cut = cut || c.objects.size() > 1;
  }
  EXPECT_TRUE(cut);
}

// Box A is put down at frame 10, box B flush beside it at frame 40. From then on the
// segmentation gives A's four right columns to B. Split by arrival, those columns are a piece
// of A's arrival, and it joins the rest of A instead of standing as an object of its own.
TEST(PartitionPrior, APieceOfAnOlderObjectGivenToANewerNeighbourGoesBackToIt) {
  PartitionPriorParams alone = Arrival();
  alone.arrival_rejoin_min_contact = 0;
  alone.arrival_join_min_contact = 0;  // which would join the columns to A as well
  PartitionPrior prior(Arrival(), TemporalFilterParams{});
  PartitionPrior without(alone, TemporalFilterParams{});
  const auto depth = [](int64_t seq) {
    return SceneOf([seq](int u, int v) {
      if (v < 10 || v >= 40) return 1.0f;
      if (u >= 10 && u < 30 && seq >= 10) return 0.9f;
      if (u >= 30 && u < 50 && seq >= 40) return 0.9f;
      return 1.0f;
    });
  };
  const auto segmented = [](int64_t seq) {
    return Segmentation([seq](int u, int v) {
      if (v < 10 || v >= 40 || seq < 10 || u < 10) return 0u;
      if (seq < 40) return u < 30 ? 1u : 0u;
      return u < 26 ? 1u : u < 50 ? 2u : 0u;
    });
  };
  bool joined = false;
  for (int64_t seq = 1; seq < 80; ++seq) {
    const auto [r, w] = ApplyBoth(&prior, &without, depth(seq), seq, segmented(seq));
    joined = joined || prior.counts().arrival_joins > 0;
    if (seq < 60) continue;  // B confirmed and its partition no longer held
    ASSERT_EQ(r.objects.size(), 2u) << seq;
    EXPECT_EQ(At(r, 11, 20), At(r, 29, 20)) << seq;
    EXPECT_NE(At(r, 29, 20), At(r, 30, 20)) << seq;
    EXPECT_EQ(At(r, 30, 20), At(r, 49, 20)) << seq;
    EXPECT_EQ(w.objects.size(), 3u) << seq;  // without: A's columns stand alone
    EXPECT_NE(At(w, 25, 20), At(w, 26, 20)) << seq;
  }
  EXPECT_TRUE(joined);
}

// A cup is put down at frame 10: the segmentation gives its inside (rows 10-19, 8 cm behind)
// and its outside wall (rows 23-39) as two segments, three unlabelled rows of rim and shadow
// apart. The pieces arrived together, so they are one object; with the join off they stay two.
// Box B, put down flush beside the wall two frames later (within arrival_gap_frames, one
// arrival group with the cup) and touching it, did not arrive in the cup's frame: it is never
// joined, nor are the first frame's surfaces (the box D, there from the start, touching the
// outside wall's other side).
TEST(PartitionPrior, PiecesOfOneObjectPutDownTogetherAreOneObject) {
  PartitionPriorParams apart = Arrival();
  apart.arrival_join_min_contact = 0;
  PartitionPriorParams joining = Arrival();
  joining.arrival_join_min_contact = 3;
  PartitionPrior prior(joining, TemporalFilterParams{});
  PartitionPrior without(apart, TemporalFilterParams{});
  const auto depth = [](int64_t seq) {
    return SceneOf([seq](int u, int v) {
      if (u >= 10 && u < 20 && v >= 23 && v < 40) return 0.9f;  // D, from the start
      if (v >= 10 && v < 40 && u >= 20 && u < 40 && seq >= 10) {
        if (v < 20) return 0.98f;  // the inside
        if (v < 23) return NAN;    // rim and shadow: no depth
        return 0.9f;               // the outside wall
      }
      if (v >= 23 && v < 40 && u >= 40 && u < 60 && seq >= 12) return 0.9f;  // B
      return 1.0f;
    });
  };
  const auto segmented = [](int64_t seq) {
    return Segmentation([seq](int u, int v) {
      if (u >= 10 && u < 20 && v >= 23 && v < 40) return 1u;
      if (seq < 10 || v < 10 || v >= 40) return 0u;
      if (u >= 20 && u < 40) return v < 20 ? 2u : v < 23 ? 0u : 3u;
      return seq >= 12 && v >= 23 && u >= 40 && u < 60 ? 4u : 0u;
    });
  };
  bool joined = false;
  for (int64_t seq = 1; seq < 80; ++seq) {
    const auto [r, w] = ApplyBoth(&prior, &without, depth(seq), seq, segmented(seq));
    joined = joined || prior.counts().arrival_joins > 0;
    EXPECT_EQ(w.objects.size(), seq < 10 ? 1u : seq < 12 ? 3u : 4u) << seq;
    if (seq < 25) continue;  // confirmed and no longer held
    ASSERT_EQ(r.objects.size(), 3u) << seq;
    EXPECT_EQ(At(r, 30, 15), At(r, 30, 30)) << seq;  // the cup is one object
    EXPECT_NE(At(r, 30, 30), At(r, 15, 30)) << seq;  // not joined with D
    EXPECT_NE(At(r, 30, 30), At(r, 50, 30)) << seq;  // nor with B
  }
  EXPECT_TRUE(joined);
}

// A long box A (columns 10-69) is put down at frame 10; at frame 30 box C is put down across
// its middle (columns 36-43, nearer), its shadow a hole of three columns beside it. The
// segmentation gives A's two ends apart from then on: they arrived together, and what lies
// between them is in front of both, so they are one object, hidden in its middle. Box B, put
// down at frame 20 beyond A's right end and seen the same way behind an occluder D, did not
// arrive with A: it stays an object of its own. With the join off, A's ends stay two.
TEST(PartitionPrior, EndsOfOneObjectOnEitherSideOfAnOccluderAreOneObject) {
  PartitionPriorParams apart = Arrival();
  apart.arrival_join_min_contact = 0;
  PartitionPrior prior(Arrival(), TemporalFilterParams{});
  PartitionPrior without(apart, TemporalFilterParams{});
  const auto a_row = [](int v) { return v >= 20 && v < 35; };
  const auto depth = [&](int64_t seq) {
    return SceneOf([&, seq](int u, int v) {
      if (!a_row(v)) return 1.0f;
      if (seq >= 30 && u >= 36 && u < 44) return 0.85f;  // C
      if (seq >= 30 && u >= 33 && u < 36) return NAN;    // C's shadow
      if (u >= 10 && u < 70 && seq >= 10) return 0.95f;  // A
      return 1.0f;
    });
  };
  const auto segmented = [&](int64_t seq) {
    return Segmentation([&, seq](int u, int v) {
      if (!a_row(v) || seq < 10 || u < 10 || u >= 70) return 0u;
      if (seq < 30) return 1u;
      if (u < 33) return 1u;
      if (u < 36) return 0u;
      return u < 44 ? 2u : 3u;
    });
  };
  bool joined = false;
  for (int64_t seq = 1; seq < 80; ++seq) {
    const auto [r, w] = ApplyBoth(&prior, &without, depth(seq), seq, segmented(seq));
    joined = joined || prior.counts().arrival_joins > 0;
    if (seq < 35) continue;  // the split of the still box is held for hold_frames without
    EXPECT_EQ(w.objects.size(), 3u) << seq;
    EXPECT_NE(At(w, 20, 25), At(w, 60, 25)) << seq;
    ASSERT_EQ(r.objects.size(), 2u) << seq;
    EXPECT_EQ(At(r, 20, 25), At(r, 60, 25)) << seq;  // A's ends
    EXPECT_NE(At(r, 20, 25), At(r, 40, 25)) << seq;  // not C
  }
  EXPECT_TRUE(joined);
}

// Two boxes put down ten frames apart (columns 10-35 at frame 10, 44-69 at frame 20) with the
// table seen between them, and box C put down at frame 40 across that gap: they did not
// arrive together, so they stay two objects. Nor are two pieces of one arrival (columns 10-29
// and 46-69, both at frame 10) joined across C when the table is seen between them and it.
TEST(PartitionPrior, PiecesApartAcrossAnOccluderStayApartUnlessTheyArrivedTogether) {
  struct Layout {
    int left_end, c_begin, c_end, right_begin;
    int64_t right_arrives;
  };
  for (const Layout& at : {Layout{36, 36, 44, 44, 20}, Layout{30, 38, 46, 46, 10}}) {
    PartitionPrior prior(Arrival(), TemporalFilterParams{});
    const auto depth = [&](int64_t seq) {
      return SceneOf([&, seq](int u, int v) {
        if (v < 20 || v >= 35) return 1.0f;
        if (seq >= 40 && u >= at.c_begin && u < at.c_end) return 0.85f;  // C
        if (seq >= 10 && u >= 10 && u < at.left_end) return 0.95f;
        if (seq >= at.right_arrives && u >= at.right_begin && u < 70) return 0.95f;
        return 1.0f;
      });
    };
    const auto segmented = [&](int64_t seq) {
      return Segmentation([&, seq](int u, int v) {
        if (v < 20 || v >= 35) return 0u;
        if (seq >= 40 && u >= at.c_begin && u < at.c_end) return 2u;
        if (seq >= 10 && u >= 10 && u < at.left_end) return 1u;
        if (seq >= at.right_arrives && u >= at.right_begin && u < 70) return 3u;
        return 0u;
      });
    };
    for (int64_t seq = 1; seq < 80; ++seq) {
      SegmentationResult r = segmented(seq);
      prior.Apply(depth(seq), seq, &r);
      if (seq < 45) continue;
      ASSERT_EQ(r.objects.size(), 3u) << seq << " right piece at frame " << at.right_arrives;
      EXPECT_NE(At(r, 20, 25), At(r, 60, 25))
          << seq << " right piece at frame " << at.right_arrives;
    }
  }
}

// The whole scene changes from frame 0 to frame 1 (a camera turned, a synthetic source): a
// new view. The only arrivals known in frame 1 are those of the pixels that had no depth in
// frame 0, measured for the first time (156 of each segment's 600); they arrived with
// everything else in view, so the two touching segments are not joined. (A box C stands in
// both frames, so that frame 0 has a segment.)
TEST(PartitionPrior, SegmentsOfANewViewAreNotJoined) {
  PartitionPriorParams joining = Arrival();
  joining.arrival_join_min_contact = 3;
  joining.hold_frames = 1;  // this frame's partition, not held
  PartitionPrior prior(joining, TemporalFilterParams{});
  for (int64_t seq = 0; seq < 2; ++seq) {
    const core::PointCloud cloud = SceneOf([seq](int u, int v) {
      if (u >= 60 && u < 70 && v >= 45 && v < 55) return 0.9f;  // C
      if (seq == 0) return u >= 24 && u < 36 && v >= 12 && v < 38 ? NAN : 1.0f;
      return v >= 10 && v < 40 && u >= 10 && u < 50 ? 0.8f : 1.1f;  // the table too
    });
    SegmentationResult r = Segmentation([seq](int u, int v) {
      if (u >= 60 && u < 70 && v >= 45 && v < 55) return seq == 0 ? 1u : 3u;
      if (seq == 0 || v < 10 || v >= 40 || u < 10 || u >= 50) return 0u;
      return u < 30 ? 1u : 2u;
    });
    prior.Apply(cloud, seq, &r);
    if (seq == 1) {
      ASSERT_EQ(r.objects.size(), 3u);
      EXPECT_NE(At(r, 20, 25), At(r, 40, 25));
    }
  }
}

// Boxes A and B stand touching from the first frame; at frame 1 the camera is moved 5 cm
// towards them, and everything in view arrives anew at once (confirmed at frame 5). A and B
// arrived in a new view: they are not joined.
TEST(PartitionPrior, TouchingObjectsSeenAgainAfterTheCameraMovedAreNotJoined) {
  PartitionPriorParams joining = Arrival();
  joining.arrival_join_min_contact = 3;
  PartitionPrior prior(joining, TemporalFilterParams{});
  for (int64_t seq = 0; seq < 30; ++seq) {
    const float moved = seq == 0 ? 0.f : 0.05f;
    const core::PointCloud cloud = SceneOf([moved](int u, int v) {
      return (v >= 10 && v < 40 && u >= 10 && u < 50 ? 0.9f : 1.0f) - moved;
    });
    SegmentationResult r = Segmentation([](int u, int v) {
      if (v < 10 || v >= 40 || u < 10 || u >= 50) return 0u;
      return u < 30 ? 1u : 2u;
    });
    prior.Apply(cloud, seq, &r);
    ASSERT_EQ(r.objects.size(), 2u) << seq;
    EXPECT_NE(At(r, 20, 25), At(r, 40, 25)) << seq;
  }
}

// The objects by arrival are the same whatever the pool: a frame of three chunks of pixels
// (core::kPixelGrain) whose boxes cross the chunks' boundaries. Box A (columns 40-159) is put
// down at frame 10, box B beside it (columns 160-279) at frame 30, and the segmentation gives
// both as one segment from then on: split by their arrivals, with no pool and on pools of two
// and three threads alike.
// Alone, on pools of two and three, and in the daemon's two halves (Relabel, publish, Remember).
TEST(PartitionPrior, TheSameObjectsByArrivalOnAPoolOfAnySizeAndInTwoHalves) {
  constexpr int w = 320, h = 240;
  static_assert(static_cast<size_t>(w * h) > 2 * core::kPixelGrain);
  const auto in_box = [](int u, int v, int64_t seq) {
    if (v < 60 || v >= 200) return false;
    return (u >= 40 && u < 160 && seq >= 10) || (u >= 160 && u < 280 && seq >= 30);
  };
  const auto cloud = [&](int64_t seq) {
    core::PointCloud c;
    c.width = w;
    c.height = h;
    c.xyz.resize(static_cast<size_t>(w * h));
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const float z = in_box(u, v, seq) ? 0.9f : 1.0f;
        c.xyz[static_cast<size_t>(v * w + u)] =
            core::Vec3f{(u - w / 2) * 0.002f * z, (v - h / 2) * 0.002f * z, z};
      }
    }
    return c;
  };
  const auto segmented = [&](int64_t seq) {
    SegmentationResult r;
    r.width = r.labels.width = w;
    r.height = r.labels.height = h;
    r.labels.data.resize(static_cast<size_t>(w * h));
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        r.labels.data[static_cast<size_t>(v * w + u)] = in_box(u, v, seq) ? 1u : 0u;
      }
    }
    r.objects.assign(seq >= 10 ? 1 : 0, Object{});
    for (size_t k = 0; k < r.objects.size(); ++k) r.objects[k].id = static_cast<uint32_t>(k + 1);
    return r;
  };
  core::ThreadPool two(2), three(3);
  PartitionPrior alone(Arrival(), TemporalFilterParams{});
  PartitionPrior on_two(Arrival(), TemporalFilterParams{}, &two);
  PartitionPrior on_three(Arrival(), TemporalFilterParams{}, &three);
  PartitionPrior halves(Arrival(), TemporalFilterParams{}, &two);
  int splits = 0;
  for (int64_t seq = 1; seq < 60; ++seq) {
    const core::PointCloud c = cloud(seq);
    SegmentationResult r = segmented(seq), r2 = r, r3 = r, r4 = r;
    const bool changed = alone.Apply(c, seq, &r);
    on_two.Apply(c, seq, &r2);
    on_three.Apply(c, seq, &r3);
    EXPECT_EQ(halves.Relabel(c, seq, &r4), changed) << seq;
    halves.Remember();
    halves.Remember();  // nothing pending: does nothing
    EXPECT_EQ(r4.labels.data, r.labels.data) << seq;
    splits += alone.counts().arrival_splits;
    ASSERT_EQ(r2.objects.size(), r.objects.size()) << seq;
    ASSERT_EQ(r3.objects.size(), r.objects.size()) << seq;
    EXPECT_EQ(r2.labels.data, r.labels.data) << seq;
    EXPECT_EQ(r3.labels.data, r.labels.data) << seq;
    EXPECT_EQ(on_two.counts().arrival_splits, alone.counts().arrival_splits) << seq;
    if (seq >= 40) {  // B arrived 20 frames after A: two objects
      ASSERT_EQ(r.objects.size(), 2u) << seq;
      EXPECT_NE(r.labels.data[100 * w + 100], r.labels.data[100 * w + 200]) << seq;
    }
  }
  EXPECT_GT(splits, 0);
}

TEST(PartitionPrior, RefusesBadParameters) {
  const std::function<void(PartitionPriorParams*)> bad[] = {
      [](PartitionPriorParams* p) { p->hold_frames = 0; },
      [](PartitionPriorParams* p) { p->min_cover_share = 0.4f; },
      [](PartitionPriorParams* p) { p->min_still_share = 0.f; },
      [](PartitionPriorParams* p) { p->arrival_gap_frames = -1; },
      [](PartitionPriorParams* p) { p->arrival_confirm_frames = 0; },
      [](PartitionPriorParams* p) { p->arrival_min_share = 0.f; },
      [](PartitionPriorParams* p) { p->arrival_moved_min_pixels = 0; },
      [](PartitionPriorParams* p) { p->arrival_rejoin_min_contact = -1; },
      [](PartitionPriorParams* p) { p->arrival_join_min_contact = -1; },
  };
  for (size_t k = 0; k < std::size(bad); ++k) {
    PartitionPriorParams p;
    bad[k](&p);
    EXPECT_THROW(p.ValidateOrThrow(), std::invalid_argument) << k;
    EXPECT_THROW(PartitionPrior(p, TemporalFilterParams{}), std::invalid_argument) << k;
  }
  EXPECT_NO_THROW(PartitionPriorParams{}.ValidateOrThrow());
}

}  // namespace
}  // namespace clutterseg::pipeline
