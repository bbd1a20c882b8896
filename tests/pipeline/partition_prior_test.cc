// PartitionPrior: a merge or split of still objects is published only after hold_frames
// frames in a row; anything that moved, and the first frames after a change, pass at once.
#include "clutterseg/pipeline/partition_prior.h"

#include <cmath>
#include <functional>
#include <limits>

#include <gtest/gtest.h>

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

PartitionPriorParams Hold(int frames) {
  PartitionPriorParams p;
  p.hold_frames = frames;
  return p;
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

TEST(PartitionPrior, RefusesBadParameters) {
  PartitionPriorParams p;
  p.hold_frames = 0;
  EXPECT_THROW(p.ValidateOrThrow(), std::invalid_argument);
  p = PartitionPriorParams{};
  p.min_cover_share = 0.4f;
  EXPECT_THROW(p.ValidateOrThrow(), std::invalid_argument);
  p = PartitionPriorParams{};
  p.min_still_share = 0.f;
  EXPECT_THROW(PartitionPrior(p, TemporalFilterParams{}), std::invalid_argument);
}

}  // namespace
}  // namespace clutterseg::pipeline
