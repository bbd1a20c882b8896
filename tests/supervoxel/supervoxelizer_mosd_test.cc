// Supervoxels of real Kinect frames (mOSD learn split, ../shared/data/mosd-learn).
#include <algorithm>
#include <cstdio>
#include <string>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/supervoxel/supervoxelizer.h"
#include "tests/supervoxel/purity.h"
#include "tests/testing/test_data.h"

namespace clutterseg::supervoxel {
namespace {

// Ground-truth region of a point: table parts (1..9) are one region, object parts keep their
// part label.
uint32_t Region(uint32_t label) { return label < 10 ? 1u : label; }

struct Quality {
  double leaked_fraction;  // points outside their supervoxel's majority region
  size_t supervoxels;
};

Quality Measure(const core::PointCloud& cloud, const Supervoxels& sv) {
  size_t total = 0, leaked = 0;
  for (const Purity& p : SupervoxelPurity(sv, [&](size_t i) { return Region(cloud.label[i]); })) {
    total += p.total;
    leaked += p.total - p.majority;
  }
  return {total > 0 ? static_cast<double>(leaked) / total : 0.0, sv.size()};
}

class MosdRealDataFrames : public ::testing::TestWithParam<const char*> {};

TEST_P(MosdRealDataFrames, LabelsEveryPointRespectsObjectsAndIsDeterministic) {
  const std::string rel = std::string("mosd-learn/") + GetParam() + ".pcd";
  CLUTTERSEG_REQUIRE_DATA(rel);
  const core::PointCloud cloud = io::ReadPcd((clutterseg::testing::DataDir() / rel).string());
  ASSERT_EQ(cloud.width, 640);
  ASSERT_EQ(cloud.height, 480);
  ASSERT_EQ(cloud.label.size(), cloud.size());

  for (bool camera_transform : {true, false}) {
    SupervoxelParams params;
    params.grid.use_single_camera_transform = camera_transform;
    Supervoxelizer dut(params);
    Supervoxels out;
    dut.Compute(cloud, &out);
    for (size_t i = 0; i < cloud.size(); ++i) {
      ASSERT_EQ(out.pixel_label[i] >= 0, core::IsValid(cloud.xyz[i])) << "pixel " << i;
    }
    size_t sum = 0;
    for (uint32_t c : out.num_points) sum += c;
    EXPECT_EQ(sum, cloud.CountValid());
    // A tabletop at about 1 m with 3 cm seeds: hundreds of supervoxels, not thousands of
    // fragments.
    EXPECT_GT(out.size(), 100u);
    EXPECT_LT(out.size(), 6000u);
    const Quality q = Measure(cloud, out);
    // Supervoxels must hug object borders: few points end in a supervoxel dominated by
    // another object or the table.
    EXPECT_LT(q.leaked_fraction, 0.03) << (camera_transform ? "camera" : "euclidean");
    std::printf("%s %s: %zu voxels, %zu seeds, %zu supervoxels, leaked %.4f\n", GetParam(),
                camera_transform ? "camera-transform" : "euclidean", dut.voxels().size(),
                dut.num_seeds(), q.supervoxels, q.leaked_fraction);

    core::ThreadPool pool(2);
    Supervoxelizer parallel_dut(params, &pool);
    Supervoxels parallel;
    parallel_dut.Compute(cloud, &parallel);
    EXPECT_EQ(parallel.pixel_label, out.pixel_label);
    EXPECT_EQ(parallel.adjacency, out.adjacency);
    EXPECT_EQ(parallel.curvature, out.curvature);
  }
}

INSTANTIATE_TEST_SUITE_P(Learn, MosdRealDataFrames,
                         ::testing::Values("learn0", "learn10", "learn20", "learn30", "learn40"),
                         [](const ::testing::TestParamInfo<const char*>& param_info) {
                           return std::string(param_info.param);
                         });

}  // namespace
}  // namespace clutterseg::supervoxel
