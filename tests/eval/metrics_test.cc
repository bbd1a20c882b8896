#include "clutterseg/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/eval/report.h"

namespace clutterseg::eval {
namespace {

constexpr double kTol = 1e-12;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// A frame whose points are all valid except those listed in `invalid`.
struct Frame {
  std::vector<core::Vec3f> xyz;
  std::vector<uint32_t> gt;
  std::vector<uint32_t> pred;
};

Frame MakeFrame(std::vector<uint32_t> gt, std::vector<uint32_t> pred,
                const std::vector<size_t>& invalid = {}) {
  Frame f;
  f.gt = std::move(gt);
  f.pred = std::move(pred);
  for (size_t k = 0; k < f.gt.size(); ++k) {
    f.xyz.push_back(core::Vec3f{0.01f * static_cast<float>(k), 0.f, 1.f});
  }
  for (size_t k : invalid) f.xyz[k].z = kNaN;
  return f;
}

FrameMetrics Score(const Frame& f, const EvalParams& params = {}) {
  FrameEvaluator dut(params);
  FrameMetrics m;
  dut.Evaluate(f.xyz, f.gt, f.pred, &m);
  return m;
}

// n copies of v.
std::vector<uint32_t> Rep(size_t n, uint32_t v) { return std::vector<uint32_t>(n, v); }

std::vector<uint32_t> Cat(std::initializer_list<std::vector<uint32_t>> parts) {
  std::vector<uint32_t> out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

void ExpectPerfect(const FrameMetrics& m) {
  EXPECT_TRUE(m.scored);
  EXPECT_NEAR(m.wov, 1.0, kTol);
  EXPECT_NEAR(m.tp, 1.0, kTol);
  EXPECT_NEAR(m.fp, 0.0, kTol);
  EXPECT_NEAR(m.fn, 0.0, kTol);
  EXPECT_NEAR(m.precision, 1.0, kTol);
  EXPECT_NEAR(m.recall, 1.0, kTol);
  EXPECT_NEAR(m.f1, 1.0, kTol);
  EXPECT_EQ(m.over_segmented, 0);
  EXPECT_EQ(m.under_segmented, 0);
}

TEST(MetricsTest, IdentityIsPerfect) {
  const auto labels = Cat({Rep(3, 0), Rep(5, 1), Rep(4, 2), Rep(2, 0), Rep(3, 7)});
  const FrameMetrics m = Score(MakeFrame(labels, labels));
  ExpectPerfect(m);
  EXPECT_EQ(m.num_gt_objects, 3);
  EXPECT_EQ(m.num_segments, 3);
  EXPECT_EQ(m.num_valid_points, labels.size());
  ASSERT_EQ(m.objects.size(), 3u);
  EXPECT_EQ(m.objects[2].gt_id, 7u);
  EXPECT_EQ(m.objects[2].best_segment, 7u);
  EXPECT_EQ(m.objects[2].size, 3u);
}

TEST(MetricsTest, RenamedSegmentsArePerfect) {
  const auto gt = Cat({Rep(3, 0), Rep(5, 1), Rep(4, 2)});
  const auto pred = Cat({Rep(3, 0), Rep(5, 40), Rep(4, 9)});
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  ExpectPerfect(m);
  EXPECT_EQ(m.objects[0].best_segment, 40u);
  EXPECT_EQ(m.objects[1].best_segment, 9u);
}

// GT: object 1 = 6 points, object 2 = 4 points, 2 background points. One segment (5) holds
// all 10 object points.
//   g1: |g∩s| = 6, |g∪s| = 10, Ov = 0.6;  g2: 4 / 10 = 0.4.
//   WOv = (6*0.6 + 4*0.4) / 10 = 0.52.
//   TP_1 = 6/6 = 1, FP_1 = 4/10 = 0.4, FN_1 = 0;  TP_2 = 1, FP_2 = 6/10 = 0.6, FN_2 = 0.
//   TP = 1, FP = 0.5, FN = 0;  P = 1/1.5 = 2/3, R = 1, F1 = 2*(2/3)/(5/3) = 0.8.
//   Segment 5 covers both objects: 2 under-segmented, 0 over-segmented.
TEST(MetricsTest, TwoObjectsMergedIntoOneSegment) {
  const auto gt = Cat({Rep(6, 1), Rep(4, 2), Rep(2, 0)});
  const auto pred = Cat({Rep(10, 5), Rep(2, 0)});
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  EXPECT_NEAR(m.wov, 0.52, kTol);
  EXPECT_NEAR(m.tp, 1.0, kTol);
  EXPECT_NEAR(m.fp, 0.5, kTol);
  EXPECT_NEAR(m.fn, 0.0, kTol);
  EXPECT_NEAR(m.precision, 2.0 / 3.0, kTol);
  EXPECT_NEAR(m.recall, 1.0, kTol);
  EXPECT_NEAR(m.f1, 0.8, kTol);
  EXPECT_EQ(m.under_segmented, 2);
  EXPECT_EQ(m.over_segmented, 0);
  EXPECT_EQ(m.num_segments, 1);
  EXPECT_NEAR(m.objects[0].overlap, 0.6, kTol);
  EXPECT_NEAR(m.objects[1].fp, 0.6, kTol);
}

// GT: one object of 10 points, 2 background points. Segments 1 (7 points) and 2 (3 points).
//   Ov = max(7/10, 3/10) = 0.7 = WOv. s = segment 1: TP = 0.7, FP = 0, FN = 0.3.
//   P = 1, R = 0.7, F1 = 1.4/1.7. Both segments hold >= 10%: over-segmented.
TEST(MetricsTest, OneObjectSplitInTwo) {
  const auto gt = Cat({Rep(10, 1), Rep(2, 0)});
  const auto pred = Cat({Rep(7, 1), Rep(3, 2), Rep(2, 0)});
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  EXPECT_NEAR(m.wov, 0.7, kTol);
  EXPECT_NEAR(m.tp, 0.7, kTol);
  EXPECT_NEAR(m.fp, 0.0, kTol);
  EXPECT_NEAR(m.fn, 0.3, kTol);
  EXPECT_NEAR(m.precision, 1.0, kTol);
  EXPECT_NEAR(m.recall, 0.7, kTol);
  EXPECT_NEAR(m.f1, 1.4 / 1.7, kTol);
  EXPECT_EQ(m.over_segmented, 1);
  EXPECT_EQ(m.under_segmented, 0);
  EXPECT_EQ(m.objects[0].covering_segments, 2);
  EXPECT_EQ(m.objects[0].best_segment, 1u);
}

// GT: object of 8 points and 4 background points; segment 1 holds the object plus 2
// background points.
//   Ov = 8/10 = WOv = 0.8; TP = 1, FP = 2/10 = 0.2, FN = 0; P = 1/1.2 = 5/6, R = 1,
//   F1 = 2*(5/6)/(11/6) = 10/11. Background is not an object: no under-segmentation.
TEST(MetricsTest, LeakageOntoBackgroundIsFalsePositive) {
  const auto gt = Cat({Rep(8, 1), Rep(4, 0)});
  const auto pred = Cat({Rep(10, 1), Rep(2, 0)});
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  EXPECT_NEAR(m.wov, 0.8, kTol);
  EXPECT_NEAR(m.tp, 1.0, kTol);
  EXPECT_NEAR(m.fp, 0.2, kTol);
  EXPECT_NEAR(m.fn, 0.0, kTol);
  EXPECT_NEAR(m.precision, 5.0 / 6.0, kTol);
  EXPECT_NEAR(m.recall, 1.0, kTol);
  EXPECT_NEAR(m.f1, 10.0 / 11.0, kTol);
  EXPECT_EQ(m.under_segmented, 0);
  EXPECT_EQ(m.objects[0].best_segment_size, 10u);
}

// Empty prediction: no segment overlaps anything, so TP_i = 0, FN_i = 1, FP_i = 0 and the
// precision 0/0 is defined as 0.
// Object 1: 80 points in segment 1, a piece of 20 alone in segment 2. Object 2: 95 in
// segment 4 with 10 background points, 5 in object 1's segment. Objects 3 (100) and 4 (50):
// one segment, 3. Background: 50 points, 10 of them in segment 4.
TEST(MetricsTest, TheLostOverlapIsSharedByCause) {
  const Frame f = MakeFrame(
      Cat({Rep(100, 1), Rep(100, 2), Rep(100, 3), Rep(50, 4), Rep(50, 0)}),
      Cat({Rep(80, 1), Rep(20, 2), Rep(95, 4), Rep(5, 1), Rep(150, 3), Rep(10, 4), Rep(40, 0)}));
  const FrameMetrics m = Score(f);
  const double total = 350.0;
  // Each error point of object i weighs |g_i| / |g_i ∪ s_i|.
  EXPECT_NEAR(m.loss_merged, (50.0 * 100.0 / 150.0 + 100.0 * 50.0 / 150.0) / total, kTol);
  EXPECT_NEAR(m.loss_split, 20.0 * 100.0 / 105.0 / total, kTol);
  EXPECT_NEAR(m.loss_boundary, (5.0 * 100.0 / 105.0 + 5.0 * 100.0 / 110.0) / total, kTol);
  EXPECT_NEAR(m.loss_background, 10.0 * 100.0 / 110.0 / total, kTol);
  EXPECT_NEAR(m.wov + m.loss_merged + m.loss_split + m.loss_boundary + m.loss_background, 1.0,
              kTol);
}

// A method without a background label: the table is segment 9, and 20 points of object 1's
// bottom are in it. They are lost to the background, not to a piece of the object.
TEST(MetricsTest, ObjectPointsInASegmentOfTheTableAreLostToTheBackground) {
  const FrameMetrics m =
      Score(MakeFrame(Cat({Rep(100, 1), Rep(200, 0)}), Cat({Rep(80, 1), Rep(20, 9), Rep(200, 9)})));
  EXPECT_NEAR(m.wov, 0.8, kTol);
  EXPECT_NEAR(m.loss_background, 0.2, kTol);
  EXPECT_NEAR(m.loss_split, 0.0, kTol);
}

TEST(MetricsTest, AnObjectNoSegmentTouchesIsLostToTheBackground) {
  const FrameMetrics m =
      Score(MakeFrame(Cat({Rep(30, 1), Rep(10, 2)}), Cat({Rep(30, 0), Rep(10, 5)})));
  EXPECT_NEAR(m.wov, 10.0 / 40.0, kTol);
  EXPECT_NEAR(m.loss_background, 30.0 / 40.0, kTol);
  EXPECT_NEAR(m.loss_merged + m.loss_split + m.loss_boundary, 0.0, kTol);
}

TEST(MetricsTest, EmptyPredictionScoresZero) {
  const auto gt = Cat({Rep(4, 0), Rep(5, 1), Rep(3, 2)});
  const FrameMetrics m = Score(MakeFrame(gt, Rep(gt.size(), 0)));
  EXPECT_TRUE(m.scored);
  EXPECT_EQ(m.num_gt_objects, 2);
  EXPECT_EQ(m.num_segments, 0);
  EXPECT_EQ(m.wov, 0.0);
  EXPECT_EQ(m.tp, 0.0);
  EXPECT_EQ(m.fp, 0.0);
  EXPECT_EQ(m.fn, 1.0);
  EXPECT_EQ(m.precision, 0.0);
  EXPECT_EQ(m.recall, 0.0);
  EXPECT_EQ(m.f1, 0.0);
  EXPECT_EQ(m.objects[0].best_segment, 0u);
}

// Predicted label 0 never matches, even where the ground truth is also 0.
TEST(MetricsTest, PredictedZeroNeverMatches) {
  const auto gt = Cat({Rep(5, 1), Rep(5, 0)});
  const auto pred = Cat({Rep(5, 0), Rep(5, 3)});
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  EXPECT_EQ(m.wov, 0.0);
  EXPECT_EQ(m.recall, 0.0);
  EXPECT_EQ(m.objects[0].best_segment, 0u);
  EXPECT_EQ(m.num_segments, 1);
}

TEST(MetricsTest, FrameWithoutGroundTruthIsNotScored) {
  const auto gt = Rep(6, 0);
  const auto pred = Cat({Rep(3, 1), Rep(3, 0)});
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  EXPECT_FALSE(m.scored);
  EXPECT_EQ(m.num_gt_objects, 0);
  EXPECT_EQ(m.num_segments, 1);
  EXPECT_EQ(m.wov, 0.0);
}

// Invalid points carry garbage labels on both sides; ignoring them leaves a perfect score.
TEST(MetricsTest, NaNPointsAreIgnoredOnBothSides) {
  auto gt = Cat({Rep(4, 0), Rep(5, 1), Rep(3, 2), Rep(3, 1)});
  auto pred = gt;
  // Points 9..11 are object 2 but predicted 0, and points 12..14 are object 1 predicted 9.
  for (size_t k = 9; k < 12; ++k) pred[k] = 0;
  for (size_t k = 12; k < 15; ++k) pred[k] = 9;
  // Point 0 is background predicted as segment 1 (would be leakage).
  pred[0] = 1;
  Frame f = MakeFrame(gt, pred, {0, 9, 10, 11, 12, 13, 14});
  // One invalid coordinate is enough.
  f.xyz[12] = core::Vec3f{kNaN, 0.f, 1.f};
  f.xyz[13] = core::Vec3f{0.f, std::numeric_limits<float>::infinity(), 1.f};
  f.xyz[14].z = 1.f;
  f.xyz[14].x = kNaN;
  const FrameMetrics m = Score(f);
  EXPECT_EQ(m.num_points, 15u);
  EXPECT_EQ(m.num_valid_points, 8u);
  EXPECT_EQ(m.num_gt_objects, 1);  // object 2 has no valid point
  EXPECT_EQ(m.num_segments, 1);    // segment 9 and segment 1's point 0 are invalid
  ExpectPerfect(m);
  EXPECT_EQ(m.objects[0].size, 5u);

  // The same frame with every point valid is far from perfect: the mask matters.
  const FrameMetrics all_valid = Score(MakeFrame(gt, pred));
  EXPECT_LT(all_valid.wov, 0.7);
}

TEST(MetricsTest, PointCloudOverloadUsesGroundTruthValidity) {
  core::PointCloud gt;
  core::PointCloud pred;
  const Frame f =
      MakeFrame(Cat({Rep(3, 0), Rep(4, 1)}), Cat({Rep(3, 0), Rep(3, 1), Rep(1, 2)}), {6});
  gt.xyz = f.xyz;
  gt.label = f.gt;
  pred.xyz.assign(f.xyz.size(), core::Vec3f{});  // all valid: must not matter
  pred.label = f.pred;
  FrameEvaluator dut(EvalParams{});
  FrameMetrics m;
  dut.Evaluate(gt, pred, &m);
  ExpectPerfect(m);
  EXPECT_EQ(m.num_segments, 1);
}

TEST(MetricsTest, PointCloudOverloadRejectsBadInput) {
  FrameEvaluator dut(EvalParams{});
  FrameMetrics m;
  core::PointCloud gt;
  gt.xyz.assign(4, core::Vec3f{});
  gt.label.assign(4, 1);
  core::PointCloud pred = gt;
  pred.label.clear();
  EXPECT_THROW(dut.Evaluate(gt, pred, &m), std::runtime_error);
  EXPECT_THROW(dut.Evaluate(pred, gt, &m), std::runtime_error);
  pred = gt;
  pred.xyz.resize(3);
  pred.label.resize(3);
  try {
    dut.Evaluate(gt, pred, &m);
    FAIL() << "expected std::runtime_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("point counts differ"), std::string::npos);
  }
}

TEST(ConventionTest, ParseAndName) {
  for (GtConvention c : {GtConvention::kPlain, GtConvention::kMosdParts, GtConvention::kMosdObjects,
                         GtConvention::kOcid}) {
    EXPECT_EQ(ParseGtConvention(GtConventionName(c)), c);
  }
  EXPECT_EQ(GtConventionName(GtConvention::kMosdObjects), "mosd-objects");
  try {
    ParseGtConvention("mosd");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'mosd'"), std::string::npos);
  }
}

TEST(ConventionTest, PlainMapping) {
  EvalParams p;
  EXPECT_EQ(MapGroundTruthLabel(0, p), 0u);
  EXPECT_EQ(MapGroundTruthLabel(1, p), 1u);
  EXPECT_EQ(MapGroundTruthLabel(23, p), 23u);
}

TEST(ConventionTest, MosdPartsMapping) {
  EvalParams p;
  p.gt_convention = GtConvention::kMosdParts;
  for (uint32_t raw = 0; raw < 10; ++raw) EXPECT_EQ(MapGroundTruthLabel(raw, p), 0u) << raw;
  EXPECT_EQ(MapGroundTruthLabel(10, p), 10u);
  EXPECT_EQ(MapGroundTruthLabel(20, p), 20u);
  EXPECT_EQ(MapGroundTruthLabel(21, p), 21u);
  EXPECT_EQ(MapGroundTruthLabel(39, p), 39u);
}

TEST(ConventionTest, MosdObjectsMapping) {
  EvalParams p;
  p.gt_convention = GtConvention::kMosdObjects;
  for (uint32_t raw = 0; raw < 10; ++raw) EXPECT_EQ(MapGroundTruthLabel(raw, p), 0u) << raw;
  for (uint32_t raw = 20; raw < 30; ++raw) EXPECT_EQ(MapGroundTruthLabel(raw, p), 2u) << raw;
  EXPECT_EQ(MapGroundTruthLabel(30, p), 3u);
  EXPECT_EQ(MapGroundTruthLabel(39, p), 3u);
  EXPECT_EQ(MapGroundTruthLabel(123, p), 12u);
}

TEST(ConventionTest, OcidMapping) {
  EvalParams p;
  p.gt_convention = GtConvention::kOcid;
  EXPECT_EQ(MapGroundTruthLabel(0, p), 0u);
  EXPECT_EQ(MapGroundTruthLabel(1, p), 0u);
  EXPECT_EQ(MapGroundTruthLabel(2, p), 0u);
  EXPECT_EQ(MapGroundTruthLabel(3, p), 3u);
  EXPECT_EQ(MapGroundTruthLabel(17, p), 17u);
  p.ocid_background_labels = {0, 5};
  EXPECT_EQ(MapGroundTruthLabel(1, p), 1u);
  EXPECT_EQ(MapGroundTruthLabel(2, p), 2u);
  EXPECT_EQ(MapGroundTruthLabel(5, p), 0u);
}

// mOSD-style frame: table parts 1, 2; object 2 has parts 21 (2 points) and 22 (2 points);
// object 3 has part 31 (1 point). Segment 1 holds all of object 2, segment 2 object 3.
//   mosd-objects: a perfect match.
//   mosd-parts: part 21: Ov = 2/4, part 22: 2/4, part 31: 1.  WOv = (1 + 1 + 1) / 5 = 0.6.
//   TP = 1, FP = (0.5 + 0.5 + 0) / 3 = 1/3, FN = 0; P = 0.75, R = 1, F1 = 1.5/1.75.
//   plain: the table parts 1 and 2 become objects with no segment.
TEST(ConventionTest, FrameScoresUnderEachMosdConvention) {
  const std::vector<uint32_t> gt = {1, 1, 2, 21, 21, 22, 22, 31};
  const std::vector<uint32_t> pred = {0, 0, 0, 1, 1, 1, 1, 2};
  const Frame f = MakeFrame(gt, pred);
  EvalParams p;
  p.gt_convention = GtConvention::kMosdObjects;
  const FrameMetrics objects = Score(f, p);
  EXPECT_EQ(objects.num_gt_objects, 2);
  ExpectPerfect(objects);

  p.gt_convention = GtConvention::kMosdParts;
  const FrameMetrics parts = Score(f, p);
  EXPECT_EQ(parts.num_gt_objects, 3);
  EXPECT_NEAR(parts.wov, 0.6, kTol);
  EXPECT_NEAR(parts.tp, 1.0, kTol);
  EXPECT_NEAR(parts.fp, 1.0 / 3.0, kTol);
  EXPECT_NEAR(parts.precision, 0.75, kTol);
  EXPECT_NEAR(parts.recall, 1.0, kTol);
  EXPECT_NEAR(parts.f1, 1.5 / 1.75, kTol);
  EXPECT_EQ(parts.under_segmented, 2);

  p.gt_convention = GtConvention::kPlain;
  const FrameMetrics plain = Score(f, p);
  EXPECT_EQ(plain.num_gt_objects, 5);
  EXPECT_EQ(plain.objects[0].best_segment, 0u);
}

TEST(ConventionTest, OcidBackgroundListIsAnOption) {
  const std::vector<uint32_t> gt = {0, 1, 1, 2, 2, 3, 3, 4};
  const std::vector<uint32_t> pred = {0, 0, 0, 0, 0, 5, 5, 6};
  const Frame f = MakeFrame(gt, pred);
  EvalParams p;
  p.gt_convention = GtConvention::kOcid;
  ExpectPerfect(Score(f, p));
  p.ocid_background_labels = {0};
  const FrameMetrics m = Score(f, p);
  EXPECT_EQ(m.num_gt_objects, 4);  // table and floor now count, and are missed
  EXPECT_NEAR(m.recall, 0.5, kTol);
}

// Equal IoU: the larger intersection wins whatever the labels. Object of 6 points:
// segment A holds 2 of them and nothing else (IoU 2/6), segment B holds 3 of them plus 3
// background points (IoU 3/9). B is chosen: TP = 3/6, FP = 3/6.
TEST(TieBreakTest, EqualIoUPrefersLargerIntersection) {
  for (const auto& [a, b] : {std::pair<uint32_t, uint32_t>{1, 2}, {2, 1}}) {
    const auto gt = Cat({Rep(6, 1), Rep(3, 0)});
    const auto pred = Cat({Rep(2, a), Rep(3, b), Rep(1, 0), Rep(3, b)});
    const FrameMetrics m = Score(MakeFrame(gt, pred));
    EXPECT_EQ(m.objects[0].best_segment, b);
    EXPECT_EQ(m.objects[0].intersection, 3u);
    EXPECT_NEAR(m.objects[0].overlap, 1.0 / 3.0, kTol);
    EXPECT_NEAR(m.tp, 0.5, kTol);
    EXPECT_NEAR(m.fp, 0.5, kTol);
  }
}

// Equal IoU and intersection: the smaller label wins, wherever its points are.
TEST(TieBreakTest, FullTiePrefersSmallerLabel) {
  const auto gt = Rep(4, 1);
  EXPECT_EQ(Score(MakeFrame(gt, {7, 7, 3, 3})).objects[0].best_segment, 3u);
  EXPECT_EQ(Score(MakeFrame(gt, {3, 3, 7, 7})).objects[0].best_segment, 3u);
}

// "Maximum overlap" is read as maximum IoU (METHOD.md's Ov): a segment with a larger
// intersection but a lower IoU loses. Object of 10 points: A holds 6 of them plus 14
// background points (IoU 6/24), B holds the other 4 alone (IoU 4/10).
TEST(TieBreakTest, IoUDecidesBeforeIntersection) {
  const auto gt = Cat({Rep(10, 1), Rep(14, 0)});
  const auto pred = Cat({Rep(6, 1), Rep(4, 2), Rep(14, 1)});
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  EXPECT_EQ(m.objects[0].best_segment, 2u);
  EXPECT_NEAR(m.wov, 0.4, kTol);
  EXPECT_NEAR(m.tp, 0.4, kTol);
  EXPECT_NEAR(m.fp, 0.0, kTol);
  EXPECT_NEAR(m.fn, 0.6, kTol);
}

// Coverage threshold: exactly 10% covers (>=), 5% does not.
TEST(SegmentationCountTest, OverSegmentationThreshold) {
  const auto gt = Rep(20, 1);
  EXPECT_EQ(Score(MakeFrame(gt, Cat({Rep(18, 1), Rep(2, 2)}))).over_segmented, 1);
  EXPECT_EQ(Score(MakeFrame(gt, Cat({Rep(19, 1), Rep(1, 2)}))).over_segmented, 0);
  EXPECT_EQ(Score(MakeFrame(gt, Cat({Rep(18, 1), Rep(1, 2), Rep(1, 3)}))).over_segmented, 0);
}

// g1 (10 points) all in segment 1; g2 (10 points): 1 point in segment 1 (10%), 9 in
// segment 2. Segment 1 covers both: both under-segmented; g2 is also over-segmented.
//   Ov_1 = 10/11, Ov_2 = 9/10, WOv = (10*10/11 + 10*0.9) / 20.
// With a 20% threshold segment 1 no longer covers g2: no over/under-segmentation.
TEST(SegmentationCountTest, UnderSegmentationPerObject) {
  const auto gt = Cat({Rep(10, 1), Rep(10, 2)});
  const auto pred = Cat({Rep(10, 1), Rep(1, 1), Rep(9, 2)});
  const Frame f = MakeFrame(gt, pred);
  const FrameMetrics m = Score(f);
  EXPECT_EQ(m.under_segmented, 2);
  EXPECT_EQ(m.over_segmented, 1);
  EXPECT_TRUE(m.objects[1].over_segmented);
  EXPECT_NEAR(m.wov, (10.0 * 10.0 / 11.0 + 10.0 * 0.9) / 20.0, kTol);
  EvalParams p;
  p.min_coverage_percent = 20;
  const FrameMetrics strict = Score(f, p);
  EXPECT_EQ(strict.under_segmented, 0);
  EXPECT_EQ(strict.over_segmented, 0);
  EXPECT_NEAR(strict.wov, m.wov, kTol);
}

TEST(ParamsTest, ValidateNamesKeyAndValue) {
  EvalParams p;
  EXPECT_NO_THROW(p.ValidateOrThrow());
  p.min_coverage_percent = 0;
  try {
    p.ValidateOrThrow();
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("min_coverage_percent"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("0"), std::string::npos);
  }
  EXPECT_THROW(FrameEvaluator{p}, std::invalid_argument);
  p.min_coverage_percent = 101;
  EXPECT_THROW(p.ValidateOrThrow(), std::invalid_argument);
}

// Reusing an evaluator on a smaller frame must give what a fresh one gives.
TEST(EvaluatorTest, BuffersAreReusedWithoutLeakingState) {
  FrameEvaluator dut(EvalParams{});
  std::vector<uint32_t> big_gt;
  std::vector<uint32_t> big_pred;
  for (uint32_t k = 0; k < 5000; ++k) {
    big_gt.push_back(k / 100);
    big_pred.push_back((k + 37) / 90);
  }
  const Frame big = MakeFrame(big_gt, big_pred);
  FrameMetrics m;
  dut.Evaluate(big.xyz, big.gt, big.pred, &m);
  EXPECT_EQ(m.num_gt_objects, 49);
  const Frame small =
      MakeFrame(Cat({Rep(6, 1), Rep(4, 2), Rep(2, 0)}), Cat({Rep(10, 5), Rep(2, 0)}));
  dut.Evaluate(small.xyz, small.gt, small.pred, &m);
  const FrameMetrics fresh = Score(small);
  EXPECT_EQ(m.num_gt_objects, fresh.num_gt_objects);
  EXPECT_EQ(m.num_segments, fresh.num_segments);
  EXPECT_EQ(m.objects.size(), fresh.objects.size());
  EXPECT_EQ(m.wov, fresh.wov);
  EXPECT_EQ(m.f1, fresh.f1);
  EXPECT_EQ(m.under_segmented, fresh.under_segmented);
}

// Interleaved labels (no long runs) exercise the merge of the contingency table.
TEST(EvaluatorTest, InterleavedLabelsCountCorrectly) {
  std::vector<uint32_t> gt;
  std::vector<uint32_t> pred;
  for (int k = 0; k < 100; ++k) {
    gt.push_back(k % 2 == 0 ? 1 : 2);            // 50 points each
    pred.push_back(k % 4 == 3 ? 1 : k % 2 + 1);  // object 2: 25 as seg 2, 25 as seg 1
  }
  const FrameMetrics m = Score(MakeFrame(gt, pred));
  // Segment 1 = all 50 of object 1 + 25 of object 2; segment 2 = 25 of object 2.
  // Ov_1 = 50/75, Ov_2 = max(25/100, 25/50) = 0.5; WOv = (50*2/3 + 50*0.5) / 100.
  EXPECT_NEAR(m.wov, (50.0 * 2.0 / 3.0 + 25.0) / 100.0, kTol);
  EXPECT_EQ(m.objects[0].best_segment, 1u);
  EXPECT_EQ(m.objects[1].best_segment, 2u);
  EXPECT_EQ(m.objects[0].best_segment_size, 75u);
}

TEST(CountTableTest, CountsEveryKeyThroughGrowthAndClear) {
  internal::CountTable dut;
  // Includes the extreme keys and enough distinct keys to grow several times.
  std::vector<uint64_t> keys = {0, ~uint64_t{0}, uint64_t{1} << 32};
  for (uint64_t k = 1; k < 3000; ++k) keys.push_back(k * 7919 + (k % 13) * (uint64_t{1} << 32));
  for (int round = 0; round < 2; ++round) {
    dut.Clear();
    for (size_t i = 0; i < keys.size(); ++i) {
      dut.Add(keys[i], i + 1);
      dut.Add(keys[i], 1);
    }
    std::vector<std::pair<uint64_t, size_t>> entries;
    dut.AppendEntries(&entries);
    std::sort(entries.begin(), entries.end());
    std::vector<std::pair<uint64_t, size_t>> expected;
    for (size_t i = 0; i < keys.size(); ++i) expected.emplace_back(keys[i], i + 2);
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(entries, expected);
  }
}

// 640x480 frame with 10% label noise: thousands of distinct pairs, identical results from
// a fresh evaluator and a reused one.
TEST(EvaluatorTest, NoisyFullFrame) {
  const size_t n = 640 * 480;
  std::vector<uint32_t> gt(n);
  std::vector<uint32_t> pred(n);
  uint32_t state = 12345;
  const auto next = [&state] {
    state = state * 1664525u + 1013904223u;
    return state >> 8;
  };
  for (size_t k = 0; k < n; ++k) {
    gt[k] = static_cast<uint32_t>((k % 640) / 80 + 8 * (k / 640 / 120));
    pred[k] = next() % 10 == 0 ? next() % 300 : gt[k] + 1;
  }
  const Frame f = MakeFrame(gt, pred);
  const FrameMetrics m = Score(f);
  EXPECT_EQ(m.num_gt_objects, 31);  // ids 1..31; id 0 is background
  EXPECT_GE(m.num_segments, 290);
  // Object i is predicted as i + 1 on ~90% of its points, plus ~0.03% noise from the others.
  for (const ObjectScore& obj : m.objects) {
    EXPECT_EQ(obj.best_segment, obj.gt_id + 1);
    EXPECT_NEAR(obj.tp, 0.9, 0.01);
  }
  EXPECT_NEAR(m.recall, 0.9, 0.01);
}

TEST(SummaryTest, MeansOverScoredFrames) {
  std::vector<FrameMetrics> frames(3);
  frames[0] =
      Score(MakeFrame(Cat({Rep(6, 1), Rep(4, 2), Rep(2, 0)}), Cat({Rep(10, 5), Rep(2, 0)})));
  frames[1] =
      Score(MakeFrame(Cat({Rep(10, 1), Rep(2, 0)}), Cat({Rep(7, 1), Rep(3, 2), Rep(2, 0)})));
  frames[2] = Score(MakeFrame(Rep(4, 0), Rep(4, 3)));  // no ground truth: not scored
  const Summary s = Summarize(frames);
  EXPECT_EQ(s.frames, 3);
  EXPECT_EQ(s.frames_scored, 2);
  EXPECT_NEAR(s.wov, (0.52 + 0.7) / 2, kTol);
  EXPECT_NEAR(s.precision, (2.0 / 3.0 + 1.0) / 2, kTol);
  EXPECT_NEAR(s.recall, (1.0 + 0.7) / 2, kTol);
  EXPECT_NEAR(s.f1, (0.8 + 1.4 / 1.7) / 2, kTol);
  EXPECT_NEAR(s.fp, 0.25, kTol);
  EXPECT_EQ(s.gt_objects, 3);
  EXPECT_EQ(s.segments, 4);
  EXPECT_EQ(s.under_segmented, 2);
  EXPECT_EQ(s.over_segmented, 1);
  EXPECT_NEAR(s.mean_segments, 4.0 / 3.0, kTol);
  EXPECT_NEAR(s.mean_under_segmented, 2.0 / 3.0, kTol);
}

TEST(ReportTest, JsonHasTheKeysAndNullsWhenNothingIsScored) {
  const FrameMetrics frame =
      Score(MakeFrame(Cat({Rep(8, 1), Rep(4, 0)}), Cat({Rep(10, 1), Rep(2, 0)})));
  EvalParams p;
  p.gt_convention = GtConvention::kMosdParts;
  const std::string json = SummaryToJson(Summarize(std::span(&frame, 1)), p, 0);
  EXPECT_EQ(json.front(), '{');
  EXPECT_EQ(json.back(), '}');
  EXPECT_EQ(json.find('\n'), std::string::npos);
  for (const char* key :
       {"\"wov\":0.8", "\"precision\":0.8333333", "\"recall\":1", "\"f1\":0.9090909",
        "\"frames\":1", "\"tp\":1", "\"fp\":0.2", "\"fn\":0", "\"over_segmented\":0",
        "\"under_segmented\":0", "\"convention\":\"mosd-parts\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key << " in " << json;
  }
  const std::string empty = SummaryToJson(Summarize({}), EvalParams{}, 0);
  EXPECT_NE(empty.find("\"wov\":null"), std::string::npos) << empty;
  EXPECT_NE(empty.find("\"frames\":0"), std::string::npos) << empty;
}

TEST(ReportTest, CsvRowMatchesHeader) {
  const FrameMetrics frame =
      Score(MakeFrame(Cat({Rep(8, 1), Rep(4, 0)}), Cat({Rep(10, 1), Rep(2, 0)})));
  const std::string header = CsvHeader();
  const std::string row = CsvRow("a,b.pcd", frame, false);
  const auto commas = [](const std::string& s) { return std::count(s.begin(), s.end(), ','); };
  EXPECT_EQ(commas(row), commas(header) + 1);  // one comma inside the quoted name
  EXPECT_EQ(row.rfind("\"a,b.pcd\",12,12,1,1,0.8,", 0), 0u) << row;
  const FrameMetrics unscored = Score(MakeFrame(Rep(3, 0), Rep(3, 0)));
  EXPECT_NE(CsvRow("x", unscored, true).find(",0,0,,,,,,,,0,0,1"), std::string::npos)
      << CsvRow("x", unscored, true);
}

}  // namespace
}  // namespace clutterseg::eval
