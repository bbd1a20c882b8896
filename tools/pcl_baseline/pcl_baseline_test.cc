#include "tools/pcl_baseline/pcl_baseline.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "tests/testing/test_data.h"

namespace clutterseg::pcl_baseline {
namespace {

// Two boxes (ground-truth parts 20 and 30) on a table (part 1).
constexpr char kFrame[] = "mosd-learn/learn2.pcd";

bool Valid(const LabelledCloud& c, std::size_t i) { return std::isfinite(c.xyz[3 * i + 2]); }

// Checks what every output must satisfy against its input: same organization and point
// order, label 0 on invalid points, labels compacted to 1..K.
void ExpectConsistentWithInput(const LabelledCloud& input, const LabelledCloud& output,
                               const FrameReport& report) {
  ASSERT_EQ(output.width, input.width);
  ASSERT_EQ(output.height, input.height);
  ASSERT_EQ(output.label.size(), input.label.size());
  std::set<std::uint32_t> labels;
  std::size_t valid = 0;
  std::size_t labelled = 0;
  for (std::size_t i = 0; i < input.label.size(); ++i) {
    if (!Valid(input, i)) {
      ASSERT_FALSE(Valid(output, i)) << "point " << i;
      ASSERT_EQ(output.label[i], 0u) << "invalid point " << i << " got a label";
      continue;
    }
    ++valid;
    for (int k = 0; k < 3; ++k) ASSERT_EQ(output.xyz[3 * i + k], input.xyz[3 * i + k]);
    ASSERT_EQ(output.rgba[i] & 0xFFFFFFu, input.rgba[i] & 0xFFFFFFu);
    if (output.label[i] != 0) {
      ++labelled;
      labels.insert(output.label[i]);
    }
  }
  EXPECT_EQ(valid, report.valid_points);
  EXPECT_EQ(labelled, report.labelled_points);
  EXPECT_EQ(labels.size(), report.segment_count);
  if (!labels.empty()) {
    EXPECT_EQ(*labels.begin(), 1u);
    EXPECT_EQ(*labels.rbegin(), labels.size());
  }
}

// Intersection over union of the ground-truth region `gt_label` with its best segment.
double BestIou(const LabelledCloud& gt, const LabelledCloud& pred, std::uint32_t gt_label) {
  std::map<std::uint32_t, std::size_t> inter;
  std::map<std::uint32_t, std::size_t> seg_size;
  std::size_t gt_size = 0;
  for (std::size_t i = 0; i < gt.label.size(); ++i) {
    if (!Valid(gt, i)) continue;
    if (pred.label[i] != 0) ++seg_size[pred.label[i]];
    if (gt.label[i] != gt_label) continue;
    ++gt_size;
    if (pred.label[i] != 0) ++inter[pred.label[i]];
  }
  double best = 0.0;
  for (const auto& [seg, n] : inter) {
    best =
        std::max(best, static_cast<double>(n) / static_cast<double>(gt_size + seg_size[seg] - n));
  }
  return best;
}

class PclBaselineRealData : public ::testing::Test {
 protected:
  void SetUp() override { scratch_ = testing::ScratchDir("pcl_baseline"); }
  std::filesystem::path scratch_;
};

TEST_F(PclBaselineRealData, LccpLabelsEveryValidPointOfTheOriginalCloud) {
  CLUTTERSEG_REQUIRE_DATA(kFrame);
  const std::filesystem::path in = testing::DataDir() / kFrame;
  const BaselineParams params;
  const FrameReport report = SegmentPcdFile(in, scratch_ / "lccp.pcd", params);
  const LabelledCloud input = ReadLabelledPcd(in);  // the input's label field is the truth
  const LabelledCloud output = ReadLabelledPcd(scratch_ / "lccp.pcd");
  ExpectConsistentWithInput(input, output, report);

  EXPECT_GT(report.intermediate_count, 100u) << "supervoxels";
  EXPECT_GE(report.segment_count, 3u);
  // Voxels no seed reaches stay unlabelled, but they are few.
  EXPECT_GT(static_cast<double>(report.labelled_points), 0.95 * report.valid_points);
  // Each box must be recovered as one segment.
  EXPECT_GT(BestIou(input, output, 20), 0.85);
  EXPECT_GT(BestIou(input, output, 30), 0.85);
}

TEST_F(PclBaselineRealData, LccpIsDeterministic) {
  CLUTTERSEG_REQUIRE_DATA(kFrame);
  const std::filesystem::path in = testing::DataDir() / kFrame;
  BaselineParams params;
  params.use_single_camera_transform = true;
  SegmentPcdFile(in, scratch_ / "a.pcd", params);
  SegmentPcdFile(in, scratch_ / "b.pcd", params);
  EXPECT_EQ(ReadLabelledPcd(scratch_ / "a.pcd").label, ReadLabelledPcd(scratch_ / "b.pcd").label);
}

TEST_F(PclBaselineRealData, PlanesClustersRemovesTheTableAndKeepsTheObject) {
  CLUTTERSEG_REQUIRE_DATA(kFrame);
  const std::filesystem::path in = testing::DataDir() / kFrame;
  BaselineParams params;
  params.method = Method::kPlanesClusters;
  const FrameReport report = SegmentPcdFile(in, scratch_ / "planes.pcd", params);
  const LabelledCloud input = ReadLabelledPcd(in);
  const LabelledCloud output = ReadLabelledPcd(scratch_ / "planes.pcd");
  ExpectConsistentWithInput(input, output, report);

  EXPECT_GE(report.intermediate_count, 1u) << "the table plane must be found";
  std::size_t table = 0;
  std::size_t table_labelled = 0;
  for (std::size_t i = 0; i < input.label.size(); ++i) {
    if (!Valid(input, i) || input.label[i] < 1 || input.label[i] > 9) continue;
    ++table;
    if (output.label[i] != 0) ++table_labelled;
  }
  ASSERT_GT(table, 10000u);
  EXPECT_LT(static_cast<double>(table_labelled), 0.05 * table);
  EXPECT_GT(BestIou(input, output, 20), 0.85);
  EXPECT_GT(BestIou(input, output, 30), 0.85);
}

TEST(PclBaselineParams, RejectsBadInput) {
  EXPECT_THROW(ParseMethod("graphcut"), std::invalid_argument);
  EXPECT_EQ(ParseMethod(MethodName(Method::kPlanesClusters)), Method::kPlanesClusters);

  BaselineParams params;
  params.seed_resolution_m = params.voxel_resolution_m;
  EXPECT_THROW(params.ValidateOrThrow(), std::invalid_argument);
  params = BaselineParams{};
  params.smoothness_threshold = 1.5f;
  EXPECT_THROW(params.ValidateOrThrow(), std::invalid_argument);

  const std::filesystem::path missing = scratch_ / "missing.pcd";
  try {
    SegmentPcdFile(missing, scratch_ / "out.pcd", BaselineParams{});
    FAIL() << "no exception for a missing file";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.pcd"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace clutterseg::pcl_baseline
