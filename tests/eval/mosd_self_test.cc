// Real mOSD frames scored against themselves, and against their own object labels.
#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/eval/metrics.h"
#include "clutterseg/io/pcd.h"
#include "tests/testing/test_data.h"

namespace clutterseg::eval {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> MosdFrames() {
  std::vector<fs::path> frames;
  for (const auto& entry : fs::directory_iterator(testing::DataDir() / "mosd-learn")) {
    if (entry.path().extension() == ".pcd") frames.push_back(entry.path());
  }
  std::sort(frames.begin(), frames.end());
  return frames;
}

TEST(MosdSelfRealData, EveryFrameAgainstItselfIsPerfect) {
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn0.pcd");
  const std::vector<fs::path> frames = MosdFrames();
  ASSERT_EQ(frames.size(), 45u);
  for (GtConvention convention : {GtConvention::kMosdParts, GtConvention::kMosdObjects}) {
    EvalParams params;
    params.gt_convention = convention;
    FrameEvaluator dut(params);
    FrameMetrics m;
    for (const fs::path& path : frames) {
      SCOPED_TRACE(path.string() + " " + std::string(GtConventionName(convention)));
      const core::PointCloud cloud = io::ReadPcd(path.string());
      ASSERT_TRUE(cloud.has_label());
      // The prediction is the raw label image, so table parts (1..9) are predicted as
      // segments too: they are background in both conventions and must not hurt.
      core::PointCloud pred = cloud;
      // Under mosd-objects a raw part label would split its object, so the prediction
      // carries one label per object (the parts' common tens).
      if (convention == GtConvention::kMosdObjects) {
        for (uint32_t& l : pred.label) l = l < 10 ? l : l / 10 * 10;
      }
      dut.Evaluate(cloud, pred, &m);
      ASSERT_TRUE(m.scored);
      EXPECT_GE(m.num_gt_objects, 1);
      EXPECT_EQ(m.wov, 1.0);
      EXPECT_EQ(m.precision, 1.0);
      EXPECT_EQ(m.recall, 1.0);
      EXPECT_EQ(m.f1, 1.0);
      EXPECT_EQ(m.over_segmented, 0);
      EXPECT_EQ(m.under_segmented, 0);
      EXPECT_LT(m.num_valid_points, cloud.size());  // the frames have cropped NaN regions
    }
  }
}

// Predicting whole objects while scoring against parts must penalise exactly the frames
// whose objects have several visible parts, and never the others.
TEST(MosdSelfRealData, ObjectLabelsAgainstPartsPenaliseMultiPartObjects) {
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn0.pcd");
  EvalParams params;
  params.gt_convention = GtConvention::kMosdParts;
  FrameEvaluator dut(params);
  FrameMetrics m;
  int multi_part_frames = 0;
  for (const fs::path& path : MosdFrames()) {
    SCOPED_TRACE(path.string());
    const core::PointCloud cloud = io::ReadPcd(path.string());
    core::PointCloud pred = cloud;
    for (uint32_t& l : pred.label) l = l < 10 ? 0 : l / 10;
    dut.Evaluate(cloud, pred, &m);
    int parts = 0;
    int objects = 0;
    {
      EvalParams objects_params;
      objects_params.gt_convention = GtConvention::kMosdObjects;
      FrameEvaluator objects_eval(objects_params);
      FrameMetrics om;
      objects_eval.Evaluate(cloud, pred, &om);
      EXPECT_EQ(om.wov, 1.0);
      parts = m.num_gt_objects;
      objects = om.num_gt_objects;
    }
    if (parts > objects) {
      ++multi_part_frames;
      EXPECT_LT(m.wov, 1.0);
      EXPECT_LT(m.precision, 1.0);
      EXPECT_EQ(m.recall, 1.0);  // every part lies inside its object's segment
    } else {
      EXPECT_EQ(m.wov, 1.0);
    }
  }
  EXPECT_GT(multi_part_frames, 0);
}

}  // namespace
}  // namespace clutterseg::eval
