#include "clutterseg/eval/tracking_metrics.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::eval {
namespace {

constexpr core::Vec3f kA{0.f, 0.f, 1.f};
constexpr core::Vec3f kB{0.2f, 0.f, 1.f};
constexpr core::Vec3f kNearA{0.01f, 0.01f, 1.f};  // 1.4 cm from A

class TrackingEvaluatorTest : public ::testing::Test {
 protected:
  void Add(const std::vector<uint32_t>& gt, const std::vector<core::Vec3f>& gt_c,
           const std::vector<int64_t>& pred, const std::vector<core::Vec3f>& pred_c) {
    dut_.AddFrame(gt, gt_c, pred, pred_c);
  }
  TrackingEvaluator dut_;
};

TEST_F(TrackingEvaluatorTest, PerfectTrackingScoresOne) {
  for (int f = 0; f < 5; ++f) Add({1, 2}, {kA, kB}, {7, 9}, {kNearA, kB});
  const TrackingMetrics m = dut_.Summarize();
  EXPECT_EQ(m.frames, 5);
  EXPECT_EQ(m.num_gt_objects, 2);
  EXPECT_DOUBLE_EQ(m.coverage, 1.0);
  EXPECT_DOUBLE_EQ(m.identity_consistency, 1.0);
  EXPECT_EQ(m.id_switches, 0);
  EXPECT_EQ(m.id_reuse, 0);
  EXPECT_EQ(m.steady_pairs, 4);
  EXPECT_EQ(m.flicker_pairs, 0);
  ASSERT_EQ(m.objects.size(), 2u);
  EXPECT_EQ(m.objects[0].main_id, 7);
  EXPECT_EQ(m.objects[1].main_id, 9);
}

TEST_F(TrackingEvaluatorTest, SwitchesReuseCoverageAndFlicker) {
  // Object 1 carries id 7, then 8 for one frame, then 7 again: two switches, 4 of 5 frames on
  // its main id. Object 2 is missed once (no prediction within 3 cm) and later takes id 7
  // (reused), which also counts as a flicker: the predicted set changed, the scene did not.
  Add({1, 2}, {kA, kB}, {7, 9}, {kA, kB});
  Add({1, 2}, {kA, kB}, {8, 9}, {kA, kB});
  Add({1, 2}, {kA, kB}, {7}, {kA});
  Add({1, 2}, {kA, kB}, {7, 9}, {kA, kB});
  Add({1, 2}, {kA, kB}, {7, 7}, {kA, kB});
  const TrackingMetrics m = dut_.Summarize();
  EXPECT_EQ(m.gt_object_frames, 10);
  EXPECT_EQ(m.matched_object_frames, 9);
  EXPECT_DOUBLE_EQ(m.coverage, 0.9);
  ASSERT_EQ(m.objects.size(), 2u);
  EXPECT_EQ(m.objects[0].id_switches, 2);
  EXPECT_EQ(m.objects[0].main_id_frames, 4);
  EXPECT_EQ(m.objects[1].id_switches, 1);
  EXPECT_EQ(m.objects[1].main_id, 9);
  EXPECT_EQ(m.objects[1].main_id_frames, 3);
  EXPECT_DOUBLE_EQ(m.identity_consistency, 7.0 / 9.0);
  EXPECT_DOUBLE_EQ(m.min_object_consistency, 0.75);
  EXPECT_EQ(m.id_switches, 3);
  EXPECT_EQ(m.id_reuse, 1);  // id 7 on objects 1 and 2
  EXPECT_EQ(m.steady_pairs, 4);
  EXPECT_EQ(m.flicker_pairs, 4);  // {7,9}->{8,9}->{7}->{7,9}->{7,7}
}

TEST_F(TrackingEvaluatorTest, ChangesOfTheSceneAreNotFlicker) {
  Add({1}, {kA}, {3}, {kA});
  Add({1, 2}, {kA, kB}, {3, 4}, {kA, kB});  // object 2 added: not a steady pair
  Add({1, 2}, {kA, kB}, {3, 4}, {kA, kB});
  Add({1}, {kA}, {3, 4}, {kA, kB});  // removed, still reported: not a steady pair either
  const TrackingMetrics m = dut_.Summarize();
  EXPECT_EQ(m.steady_pairs, 1);
  EXPECT_EQ(m.flicker_pairs, 0);
  EXPECT_DOUBLE_EQ(m.flicker, 0.0);
}

TEST(TrackingEvaluatorSettle, PairsRightAfterAChangeAreLeftOut) {
  TrackingEvalParams params;
  params.settle_frames = 2;
  TrackingEvaluator dut(params);
  const std::vector<uint32_t> one = {1}, two = {1, 2};
  const std::vector<core::Vec3f> one_c = {kA}, two_c = {kA, kB};
  const std::vector<int64_t> p1 = {3}, p2 = {3, 4};
  dut.AddFrame(one, one_c, p1, one_c);
  dut.AddFrame(two, two_c, p1, one_c);  // object 2 added, shown two frames later
  dut.AddFrame(two, two_c, p1, one_c);
  dut.AddFrame(two, two_c, p2, two_c);
  dut.AddFrame(two, two_c, p2, two_c);
  const TrackingMetrics m = dut.Summarize();
  EXPECT_EQ(m.steady_pairs, 1);  // only (3, 4): the set has held since frame 1
  EXPECT_EQ(m.flicker_pairs, 0);
  EXPECT_THROW(TrackingEvaluator(TrackingEvalParams{0.03f, -1}), std::invalid_argument);
}

TEST_F(TrackingEvaluatorTest, RememberedIdsCountForFlickerOnly) {
  const std::vector<uint32_t> gt = {1, 2};
  const std::vector<core::Vec3f> gt_c = {kA, kB};
  const std::vector<int64_t> both = {3, 4}, one = {3}, remembered = {4};
  const std::vector<core::Vec3f> both_c = {kA, kB}, one_c = {kA};
  dut_.AddFrame(gt, gt_c, both, both_c);
  dut_.AddFrame(gt, gt_c, one, one_c, remembered);  // 4 hidden but still reported
  dut_.AddFrame(gt, gt_c, both, both_c);
  const TrackingMetrics m = dut_.Summarize();
  EXPECT_EQ(m.steady_pairs, 2);
  EXPECT_EQ(m.flicker_pairs, 0);
  EXPECT_EQ(m.matched_object_frames, 5);  // object 2 unmatched in the middle frame
}

TEST_F(TrackingEvaluatorTest, MatchesTheNearestCentroidWithinTheDistance) {
  const core::Vec3f far{0.f, 0.f, 1.04f};
  Add({1}, {kA}, {5, 6}, {far, kNearA});
  Add({1}, {kA}, {5}, {far});
  const TrackingMetrics m = dut_.Summarize();
  EXPECT_EQ(m.matched_object_frames, 1);
  EXPECT_EQ(m.objects[0].main_id, 6);
  EXPECT_THROW(TrackingEvaluator(TrackingEvalParams{0.f}), std::invalid_argument);
}

TEST(LabelCentroids, AveragesValidPointsOfLargeEnoughLabels) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<core::Vec3f> xyz = {{0, 0, 1}, {2, 0, 1}, {nan, nan, nan},
                                        {5, 5, 5}, {1, 1, 1}, {9, 9, 9}};
  const std::vector<uint32_t> labels = {3, 3, 3, 1, 0, 1};
  std::vector<uint32_t> ids;
  std::vector<core::Vec3f> c;
  LabelCentroids(xyz, labels, 2, &ids, &c);
  ASSERT_EQ(ids, (std::vector<uint32_t>{1, 3}));
  EXPECT_FLOAT_EQ(c[0].x, 7.f);
  EXPECT_FLOAT_EQ(c[1].x, 1.f);
  EXPECT_FLOAT_EQ(c[1].z, 1.f);
  LabelCentroids(xyz, labels, 3, &ids, &c);
  EXPECT_TRUE(ids.empty());
}

}  // namespace
}  // namespace clutterseg::eval
