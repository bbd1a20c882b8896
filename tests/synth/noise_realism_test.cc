// Compares the noise texture of rendered frames with real Kinect frames (mOSD): the median
// surface variation of 3 cm patches of the table at about 1 m.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/io/pcd.h"
#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/scene.h"
#include "clutterseg/synth/sensor_params.h"
#include "surface_variation.h"
#include "tests/testing/test_data.h"

namespace clutterseg::synth {
namespace {

namespace fs = std::filesystem;
using testing::CollectSurfaceVariation;
using testing::Median;
using testing::PatchOptions;

// Median patch statistic over the table (labels 1..9) of every mOSD learn frame.
double RealTableMedian(int* patches) {
  std::vector<double> values;
  const fs::path dir = clutterseg::testing::DataDir() / "mosd-learn";
  core::PointCloud cloud;
  for (int k = 0; k < 45; ++k) {
    const fs::path p = dir / ("learn" + std::to_string(k) + ".pcd");
    if (!fs::exists(p)) continue;
    io::ReadPcd(p.string(), {}, &cloud);
    std::vector<uint8_t> table(cloud.size());
    for (size_t i = 0; i < cloud.size(); ++i) table[i] = cloud.label[i] >= 1 && cloud.label[i] <= 9;
    CollectSurfaceVariation(cloud, table, PatchOptions{}, &values);
  }
  *patches = static_cast<int>(values.size());
  return Median(values);
}

// The same statistic over the table top of rendered scenes seen from about 1 m.
double RenderedTableMedian(const SensorParams& sensor, int* patches) {
  SceneParams params;
  params.camera_distance_min_m = 0.95;
  params.camera_distance_max_m = 1.05;
  std::vector<double> values;
  RenderedFrame frame;
  core::PointCloud cloud;
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    const Scene scene = GenerateScene(params, seed);
    RenderScene(scene, params.intrinsics, sensor, seed, &frame);
    ToPointCloud(frame, &cloud);
    std::vector<uint8_t> table(cloud.size());
    for (size_t i = 0; i < cloud.size(); ++i) {
      const core::Vec3f p = cloud.xyz[i];
      if (frame.true_label.data[i] != 0 || !std::isfinite(p.z)) continue;
      const Vec3 world = scene.camera_pose.Apply({p.x, p.y, p.z});
      table[i] = std::abs(world.z - scene.table_top_z_m) < 0.03;
    }
    CollectSurfaceVariation(cloud, table, PatchOptions{}, &values);
  }
  *patches = static_cast<int>(values.size());
  return Median(values);
}

TEST(NoiseRealismRealData, TablePatchVariationMatchesRealKinectFrames) {
  CLUTTERSEG_REQUIRE_DATA("mosd-learn/learn0.pcd");
  int real_patches = 0;
  const double real = RealTableMedian(&real_patches);
  ASSERT_GT(real_patches, 500);
  int patches = 0;
  const double rendered = RenderedTableMedian(SensorParams{}, &patches);
  ASSERT_GT(patches, 500);
  SensorParams independent;
  independent.axial_noise_correlation_px = 0.0;
  int independent_patches = 0;
  const double uncorrelated = RenderedTableMedian(independent, &independent_patches);
  std::printf(
      "median 3 cm patch surface variation at ~1 m: real %.4f (%d patches), rendered "
      "%.4f (%d), rendered with independent noise %.4f (%d)\n",
      real, real_patches, rendered, patches, uncorrelated, independent_patches);
  RecordProperty("real_x1e4", static_cast<int>(real * 1e4));
  RecordProperty("rendered_x1e4", static_cast<int>(rendered * 1e4));
  RecordProperty("independent_x1e4", static_cast<int>(uncorrelated * 1e4));
  // CLUTTERSEG_SWEEP_CORRELATION=1 prints the statistic against the correlation length (how
  // the default of SensorParams::axial_noise_correlation_px was chosen).
  if (std::getenv("CLUTTERSEG_SWEEP_CORRELATION") != nullptr) {
    for (double l : {2.0, 4.0, 6.0, 7.0, 8.0, 12.0, 16.0, 32.0}) {
      SensorParams s;
      s.axial_noise_correlation_px = l;
      int n = 0;
      std::printf("  correlation %5.1f px: %.4f\n", l, RenderedTableMedian(s, &n));
    }
  }
  EXPECT_NEAR(rendered, real, 0.35 * real);
  EXPECT_GT(uncorrelated, 2.0 * real);
}

}  // namespace
}  // namespace clutterseg::synth
