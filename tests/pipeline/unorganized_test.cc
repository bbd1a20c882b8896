// Unorganized clouds (HEIGHT 1) through the whole Segmenter: the labels follow the input's
// points in their order, and the quality of shuffled real and synthetic frames stays that of
// the organized run.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/eval/metrics.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/scene.h"
#include "tests/testing/test_data.h"

namespace clutterseg::pipeline {
namespace {

// The valid points of `cloud` (with their colour and labels) in a random order as one row,
// as an unorganized PCD holds them; order[k] is the index in `cloud` of point k.
core::PointCloud Shuffled(const core::PointCloud& cloud, uint64_t seed,
                          std::vector<size_t>* order) {
  order->clear();
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (core::IsValid(cloud.xyz[i])) order->push_back(i);
  }
  std::mt19937_64 rng(seed);
  std::shuffle(order->begin(), order->end(), rng);
  core::PointCloud out;
  out.width = static_cast<int>(order->size());
  out.height = 1;
  const bool color = cloud.rgba.size() == cloud.size();
  const bool label = cloud.label.size() == cloud.size();
  for (const size_t i : *order) {
    out.xyz.push_back(cloud.xyz[i]);
    if (color) out.rgba.push_back(cloud.rgba[i]);
    if (label) out.label.push_back(cloud.label[i]);
  }
  return out;
}

eval::FrameMetrics Score(const core::PointCloud& gt, const std::vector<uint32_t>& labels,
                         eval::GtConvention convention) {
  eval::EvalParams ep;
  ep.gt_convention = convention;
  eval::FrameEvaluator evaluator(ep);
  eval::FrameMetrics m;
  evaluator.Evaluate(gt.xyz, gt.label, labels, &m);
  return m;
}

// Segments `cloud` organized and shuffled; returns the two WOv. Checks that the unorganized
// result has one label per input point, in the input's order: every object is made of the
// input points its label names, and the shuffled result does not depend on the pool.
struct TwoRuns {
  double organized{0}, unorganized{0};
};
TwoRuns SegmentBoth(const core::PointCloud& cloud, const core::CameraIntrinsics& k,
                    eval::GtConvention convention, core::ThreadPool* pool, uint64_t seed) {
  TwoRuns r;
  Segmenter dut(SegmenterParams{}, pool);
  SegmentationResult organized, unorganized;
  dut.Process(cloud, k, &organized);
  r.organized = Score(cloud, organized.labels.data, convention).wov;
  std::vector<size_t> order;
  const core::PointCloud shuffled = Shuffled(cloud, seed, &order);
  dut.Process(shuffled, k, &unorganized);
  EXPECT_EQ(unorganized.width, shuffled.width);
  EXPECT_EQ(unorganized.height, 1);
  EXPECT_EQ(unorganized.labels.data.size(), shuffled.size());
  r.unorganized = Score(shuffled, unorganized.labels.data, convention).wov;
  // Object statistics count exactly the points that carry the object's label.
  std::vector<uint32_t> count(unorganized.objects.size() + 1, 0);
  for (const uint32_t l : unorganized.labels.data) {
    EXPECT_LE(l, unorganized.objects.size());
    if (l <= unorganized.objects.size()) ++count[l];
  }
  for (const Object& o : unorganized.objects) EXPECT_EQ(o.num_points, count[o.id]);
  EXPECT_GT(unorganized.objects.size(), 0u);
  return r;
}

// Synthetic rooms (seed 5 without colour), shuffled: within 0.01 WOv of the organized run
// (measured: at most 0.001 apart).
TEST(UnorganizedClouds, ShuffledSyntheticRoomsKeepTheOrganizedQuality) {
  core::ThreadPool pool(2);
  double sum_org = 0, sum_unorg = 0;
  int n = 0;
  for (uint64_t seed : {3u, 4u, 5u}) {
    synth::SceneParams p;
    p.wall_probability = 0.0;
    const synth::Scene scene = synth::GenerateScene(p, seed);
    synth::RenderedFrame frame;
    synth::RenderScene(scene, p.intrinsics, synth::SensorParams{}, seed, &frame);
    core::PointCloud cloud;
    synth::ToPointCloud(frame, &cloud);
    if (seed == 5) cloud.rgba.clear();  // a cloud without colour
    const TwoRuns r = SegmentBoth(cloud, p.intrinsics, eval::GtConvention::kPlain, &pool, seed);
    std::printf("  synthetic seed %d: organized WOv %.4f, shuffled %.4f\n", static_cast<int>(seed),
                r.organized, r.unorganized);
    EXPECT_NEAR(r.unorganized, r.organized, 0.01) << "seed " << seed;
    sum_org += r.organized;
    sum_unorg += r.unorganized;
    ++n;
  }
  EXPECT_NEAR(sum_unorg / n, sum_org / n, 0.005);
}

// The check: real mOSD frames of every category, their points shuffled into
// unorganized clouds, score within 0.01 WOv of the organized frames, each frame and on
// average (measured: at most 0.0021 apart per frame).
TEST(UnorganizedCloudsRealData, ShuffledMosdFramesStayWithinOneHundredthWov) {
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn0.pcd");
  CLUTTERSEG_REQUIRE_DATA("mosd-clutter/test44.pcd");
  core::ThreadPool pool(2);
  const std::vector<std::string> frames = {"mosd-learn/learn3.pcd",   "mosd-learn/learn20.pcd",
                                           "mosd-learn/learn29.pcd",  "mosd-learn/learn43.pcd",
                                           "mosd-clutter/test44.pcd", "mosd-clutter/test52.pcd",
                                           "mosd-clutter/test54.pcd", "mosd-clutter/test57.pcd",
                                           "mosd-clutter/test61.pcd", "mosd-clutter/test63.pcd"};
  double sum_org = 0, sum_unorg = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    const core::PointCloud cloud =
        io::ReadPcd((::clutterseg::testing::DataDir() / frames[f]).string());
    ASSERT_TRUE(cloud.organized()) << frames[f];
    const TwoRuns r = SegmentBoth(cloud, core::DefaultKinectIntrinsics(),
                                  eval::GtConvention::kMosdParts, &pool, 100 + f);
    std::printf("  %-26s organized WOv %.4f, shuffled %.4f\n", frames[f].c_str(), r.organized,
                r.unorganized);
    EXPECT_NEAR(r.unorganized, r.organized, 0.01) << frames[f];
    sum_org += r.organized;
    sum_unorg += r.unorganized;
  }
  const double n = static_cast<double>(frames.size());
  std::printf("  mean: organized %.4f, shuffled %.4f\n", sum_org / n, sum_unorg / n);
  EXPECT_NEAR(sum_unorg / n, sum_org / n, 0.01);
}

}  // namespace
}  // namespace clutterseg::pipeline
