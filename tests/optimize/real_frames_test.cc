// Features, linkage and plane labelling on real Kinect frames of the mOSD learn split,
// supervoxelized by the project's own supervoxelizer.
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/graph/linkage.h"
#include "clutterseg/graph/patch_features.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/optimize/planes.h"
#include "clutterseg/supervoxel/supervoxelizer.h"
#include "tests/testing/test_data.h"

namespace clutterseg::optimize {
namespace {

struct Frame {
  core::PointCloud cloud;
  supervoxel::Supervoxels sv;
  graph::PatchFeatures f;
};

Frame Load(const std::string& rel) {
  Frame fr;
  fr.cloud = io::ReadPcd((clutterseg::testing::DataDir() / rel).string());
  supervoxel::Supervoxelizer(supervoxel::SupervoxelParams{}).Compute(fr.cloud, &fr.sv);
  graph::PatchFeatureExtractor().Compute(fr.cloud, fr.sv, &fr.f);
  return fr;
}

// mOSD labels: 1..9 table, >= 20 object parts.
bool IsTable(uint32_t l) { return l >= 1 && l <= 9; }
bool IsObject(uint32_t l) { return l >= 20; }

TEST(RealDataFrames, TablePlaneHoldsTheTableButNotTheObjects) {
  for (const char* rel : {"mosd-learn/learn0.pcd", "mosd-learn/learn17.pcd",
                          "mosd-learn/learn25.pcd", "mosd-learn/learn40.pcd"}) {
    CLUTTERSEG_REQUIRE_DATA(rel);
    SCOPED_TRACE(rel);
    const Frame fr = Load(rel);
    ASSERT_TRUE(fr.cloud.has_label());
    ASSERT_GT(fr.sv.size(), 500u);
    PlaneLabeling out;
    PlaneLabeler(PlaneParams{}).Compute(fr.sv, fr.f, &out);
    ASSERT_FALSE(out.planes.empty());
    // The support plane: the one holding most table points.
    std::map<int32_t, size_t> table_on;
    size_t table = 0, objects = 0;
    for (size_t p = 0; p < fr.cloud.size(); ++p) {
      const int32_t s = fr.sv.pixel_label[p];
      if (s < 0) continue;
      table += IsTable(fr.cloud.label[p]) ? 1 : 0;
      objects += IsObject(fr.cloud.label[p]) ? 1 : 0;
      if (IsTable(fr.cloud.label[p]) && out.patch_plane[s] >= 0) ++table_on[out.patch_plane[s]];
    }
    int32_t support = -1;
    size_t best = 0;
    for (const auto& [plane, count] : table_on) {
      if (count > best) {
        best = count;
        support = plane;
      }
    }
    size_t objects_on_support = 0;
    for (size_t p = 0; p < fr.cloud.size(); ++p) {
      const int32_t s = fr.sv.pixel_label[p];
      if (s >= 0 && IsObject(fr.cloud.label[p]) && out.patch_plane[s] == support) {
        ++objects_on_support;
      }
    }
    ASSERT_GT(table, 10000u);
    ASSERT_GT(objects, 1000u);
    EXPECT_GT(static_cast<double>(best) / table, 0.98);
    // Supervoxels straddling an object's foot touch the table; the objects stay off it.
    EXPECT_LT(static_cast<double>(objects_on_support) / objects, 0.15);
    const PlaneModel& plane = out.planes[support];
    EXPECT_GT(plane.d, 0.f);
    EXPECT_GT(plane.num_points, best / 2);
  }
}

TEST(RealDataFrames, LinkageSeparatesObjectsAndIsThreadCountIndependent) {
  const char* rel = "mosd-learn/learn5.pcd";
  CLUTTERSEG_REQUIRE_DATA(rel);
  const Frame fr = Load(rel);
  graph::LinkageResult reference;
  graph::Linkage(graph::LinkageParams{}).Compute(fr.sv, fr.f, &reference);
  EXPECT_GT(reference.num_segments, 2);
  // The largest segment is table: it holds few object points.
  std::vector<size_t> seg_points(reference.num_segments, 0), seg_objects(reference.num_segments, 0);
  for (size_t p = 0; p < fr.cloud.size(); ++p) {
    const int32_t s = fr.sv.pixel_label[p];
    if (s < 0) continue;
    ++seg_points[reference.segment[s]];
    seg_objects[reference.segment[s]] += IsObject(fr.cloud.label[p]) ? 1 : 0;
  }
  size_t largest = 0;
  for (size_t s = 1; s < seg_points.size(); ++s) {
    if (seg_points[s] > seg_points[largest]) largest = s;
  }
  EXPECT_LT(static_cast<double>(seg_objects[largest]) / seg_points[largest], 0.05);
  for (int threads : {2, 3}) {
    core::ThreadPool pool(threads);
    graph::PatchFeatures f;
    graph::PatchFeatureExtractor(&pool).Compute(fr.cloud, fr.sv, &f);
    EXPECT_EQ(f.normal.size(), fr.f.normal.size());
    EXPECT_EQ(
        0, std::memcmp(f.normal.data(), fr.f.normal.data(), f.normal.size() * sizeof(core::Vec3f)));
    graph::LinkageResult r;
    graph::Linkage(graph::LinkageParams{}, &pool).Compute(fr.sv, f, &r);
    EXPECT_EQ(r.segment, reference.segment);
    EXPECT_EQ(r.edge_kept, reference.edge_kept);
  }
}

}  // namespace
}  // namespace clutterseg::optimize
