// The segmenter on adversarial frames: empty, degenerate, noisy, extreme and huge inputs.
// Every frame must be processed without a crash into a consistent result: labels within
// 0..objects.size() and only on valid points, object ids 1..n in order, per-object point
// counts summing to the labelled pixels, every numeric field finite.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <sys/resource.h>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"
#include "clutterseg/pipeline/segmenter.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::pipeline {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

bool Finite(const core::Vec3f& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Checks the invariants every result must satisfy; returns the number of labelled pixels.
size_t ExpectConsistent(const core::PointCloud& cloud, const SegmentationResult& result) {
  const int height = std::max(cloud.height, 1);
  EXPECT_EQ(result.width, cloud.width);
  EXPECT_EQ(result.height, height);
  EXPECT_EQ(result.labels.width, cloud.width);
  EXPECT_EQ(result.labels.height, height);
  EXPECT_EQ(result.labels.data.size(), cloud.xyz.size());
  EXPECT_LE(result.num_valid_points, cloud.xyz.size());

  const size_t n = result.objects.size();
  std::vector<uint32_t> counts(n + 1, 0);
  size_t labelled = 0;
  size_t out_of_range = 0;
  size_t on_invalid = 0;
  for (size_t i = 0; i < result.labels.data.size() && i < cloud.xyz.size(); ++i) {
    const uint32_t label = result.labels.data[i];
    if (label > n) {
      ++out_of_range;
      continue;
    }
    ++counts[label];
    if (label != 0) {
      ++labelled;
      if (!core::IsValid(cloud.xyz[i])) ++on_invalid;
    }
  }
  EXPECT_EQ(out_of_range, 0u) << "labels beyond objects.size() = " << n;
  EXPECT_EQ(on_invalid, 0u) << "object labels on invalid points";

  uint64_t sum = 0;
  for (size_t k = 0; k < n; ++k) {
    const Object& o = result.objects[k];
    SCOPED_TRACE(::testing::Message() << "object " << k);
    EXPECT_EQ(o.id, k + 1);
    EXPECT_GT(o.num_points, 0u);
    EXPECT_EQ(o.num_points, counts[k + 1]);
    sum += o.num_points;
    EXPECT_TRUE(Finite(o.centroid));
    EXPECT_TRUE(Finite(o.aabb_min));
    EXPECT_TRUE(Finite(o.aabb_max));
    EXPECT_TRUE(Finite(o.obb_center));
    EXPECT_TRUE(Finite(o.obb_extents));
    for (const core::Vec3f& axis : o.obb_axes) EXPECT_TRUE(Finite(axis));
    EXPECT_LE(o.aabb_min.x, o.aabb_max.x);
    EXPECT_LE(o.aabb_min.y, o.aabb_max.y);
    EXPECT_LE(o.aabb_min.z, o.aabb_max.z);
    EXPECT_TRUE(std::isfinite(o.confidence));
    EXPECT_GE(o.confidence, 0.f);
    EXPECT_LE(o.confidence, 1.f);
    EXPECT_GE(o.pixel_min_u, 0);
    EXPECT_LE(o.pixel_min_u, o.pixel_max_u);
    EXPECT_LT(o.pixel_max_u, cloud.width);
    EXPECT_GE(o.pixel_min_v, 0);
    EXPECT_LE(o.pixel_min_v, o.pixel_max_v);
    EXPECT_LT(o.pixel_max_v, height);
    EXPECT_GE(o.support_plane_id, -1);
  }
  EXPECT_EQ(sum, labelled);
  for (const Plane& p : result.planes) {
    EXPECT_TRUE(Finite(p.normal));
    EXPECT_TRUE(std::isfinite(p.d));
    EXPECT_TRUE(std::isfinite(p.area_m2));
    EXPECT_NEAR(
        std::sqrt(p.normal.x * p.normal.x + p.normal.y * p.normal.y + p.normal.z * p.normal.z), 1.0,
        1e-3);
  }
  return labelled;
}

core::PointCloud FromDepth(const core::DepthImage& depth) {
  const core::CameraIntrinsics k =
      core::DefaultKinectIntrinsics().Scaled(depth.width, depth.height);
  core::PointCloud cloud;
  core::DepthToPointCloud(depth, k, nullptr, &cloud);
  return cloud;
}

core::CameraIntrinsics IntrinsicsFor(const core::PointCloud& cloud) {
  return core::DefaultKinectIntrinsics().Scaled(cloud.width, std::max(cloud.height, 1));
}

SegmentationResult Segment(const core::PointCloud& cloud, const SegmenterParams& params = {}) {
  Segmenter segmenter(params);
  SegmentationResult result;
  segmenter.Process(cloud, IntrinsicsFor(cloud), &result);
  return result;
}

// A tabletop in millimetres: a plane receding from the camera with two boxes on it.
core::DepthImage Tabletop(int width, int height) {
  core::DepthImage depth(width, height, 0);
  for (int v = 0; v < height; ++v) {
    const double t = static_cast<double>(v) / std::max(1, height - 1);
    for (int u = 0; u < width; ++u) {
      double z = 1500.0 - 700.0 * t;
      const double s = static_cast<double>(u) / width;
      if (s > 0.25 && s < 0.42 && t > 0.3 && t < 0.6) z -= 110.0;
      if (s > 0.58 && s < 0.7 && t > 0.4 && t < 0.65) z -= 80.0;
      depth.at(u, v) = static_cast<uint16_t>(z);
    }
  }
  return depth;
}

SegmenterParams FarParams() {
  SegmenterParams params;
  params.points.max_depth_m = 100.f;
  return params;
}

TEST(AdversarialFrames, AllInvalidGivesEmptyResult) {
  const core::PointCloud cloud = FromDepth(core::DepthImage(640, 480, 0));
  const SegmentationResult result = Segment(cloud);
  EXPECT_EQ(ExpectConsistent(cloud, result), 0u);
  EXPECT_EQ(result.num_valid_points, 0u);
  EXPECT_TRUE(result.objects.empty());
  EXPECT_TRUE(result.planes.empty());
}

TEST(AdversarialFrames, OneValidPixel) {
  core::DepthImage depth(640, 480, 0);
  depth.at(320, 240) = 1000;
  const core::PointCloud cloud = FromDepth(depth);
  const SegmentationResult result = Segment(cloud);
  ExpectConsistent(cloud, result);
  EXPECT_EQ(result.num_valid_points, 1u);
}

TEST(AdversarialFrames, FlatWallHasNoObjects) {
  const core::PointCloud cloud = FromDepth(core::DepthImage(640, 480, 1200));
  const SegmentationResult result = Segment(cloud);
  ExpectConsistent(cloud, result);
  EXPECT_EQ(result.num_valid_points, 640u * 480u);
  // A single plane filling the view: it is a support surface, nothing stands on it.
  EXPECT_TRUE(result.objects.empty()) << result.objects.size() << " objects on a bare wall";
}

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
// Shadow memory and redzones: the bounds below are for builds without a sanitizer.
constexpr double kRssScale = 3.0;
#else
constexpr double kRssScale = 1.0;
#endif

// Peak resident set size of this process so far, MiB (each test runs in a process of its own).
double PeakRssMib() {
  rusage usage{};
  EXPECT_EQ(getrusage(RUSAGE_SELF, &usage), 0);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is KiB
}

// Every pixel at its own random depth: about 140k supervoxels of a voxel or two instead of
// about a thousand. Memory must stay linear in them: per-chunk tables of one entry per
// supervoxel, one chunk per 256 supervoxels, once took 300 MiB more (490 MiB in all) here and
// kept it for every later frame.
TEST(AdversarialFrames, UniformRandomDepthsWithMemoryLinearInSupervoxels) {
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> mm(300, 3000);
  core::DepthImage depth(640, 480);
  for (uint16_t& d : depth.data) d = static_cast<uint16_t>(mm(rng));
  const core::PointCloud cloud = FromDepth(depth);
  ExpectConsistent(cloud, Segment(cloud));
  const double peak_mib = PeakRssMib();
  RecordProperty("peak_rss_mib", static_cast<int>(peak_mib));
  std::printf("peak RSS after the random-depth frame: %.0f MiB\n", peak_mib);
  EXPECT_LT(peak_mib, 320.0 * kRssScale);
}

TEST(AdversarialFrames, RandomBitsDepths) {
  std::mt19937 rng(777);
  core::DepthImage depth(320, 240);
  for (uint16_t& d : depth.data) d = static_cast<uint16_t>(rng());
  const core::PointCloud cloud = FromDepth(depth);
  ExpectConsistent(cloud, Segment(cloud, FarParams()));
}

TEST(AdversarialFrames, ExtremeDepths) {
  for (const uint16_t mm : {uint16_t{300}, uint16_t{10000}, uint16_t{65535}}) {
    SCOPED_TRACE(::testing::Message() << mm << " mm");
    const core::PointCloud cloud = FromDepth(core::DepthImage(320, 240, mm));
    // Default range (0.3..3 m) and a range wide enough to let every depth through.
    const SegmentationResult near = Segment(cloud);
    ExpectConsistent(cloud, near);
    EXPECT_EQ(near.num_valid_points, mm == 300 ? 320u * 240u : 0u);
    const SegmentationResult far = Segment(cloud, FarParams());
    ExpectConsistent(cloud, far);
    EXPECT_EQ(far.num_valid_points, 320u * 240u);
  }
}

TEST(AdversarialFrames, MixedExtremeDepths) {
  core::DepthImage depth(320, 240);
  const uint16_t values[] = {0, 300, 301, 2999, 10000, 65535, 1};
  for (size_t i = 0; i < depth.data.size(); ++i) {
    depth.data[i] = values[(i * 7 + i / 320) % (sizeof(values) / sizeof(values[0]))];
  }
  const core::PointCloud cloud = FromDepth(depth);
  ExpectConsistent(cloud, Segment(cloud));
  ExpectConsistent(cloud, Segment(cloud, FarParams()));
}

TEST(AdversarialFrames, NonFiniteCoordinateMixtures) {
  // A tabletop whose points are mixed with NaN / inf in single coordinates, huge finite
  // coordinates (beyond any voxel index), denormals and negative depths.
  core::PointCloud cloud = FromDepth(Tabletop(320, 240));
  const float poison[] = {kNaN, kInf, -kInf, 1e30f, -1e30f, 1e-40f, -1.f, 3e38f};
  std::mt19937 rng(99);
  for (size_t i = 0; i < cloud.xyz.size(); ++i) {
    if (rng() % 4 != 0) continue;
    const float value = poison[rng() % (sizeof(poison) / sizeof(poison[0]))];
    switch (rng() % 3) {
      case 0:
        cloud.xyz[i].x = value;
        break;
      case 1:
        cloud.xyz[i].y = value;
        break;
      default:
        cloud.xyz[i].z = value;
        break;
    }
  }
  ExpectConsistent(cloud, Segment(cloud));
  ExpectConsistent(cloud, Segment(cloud, FarParams()));
}

TEST(AdversarialFrames, HugeLateralCoordinatesInRange) {
  // Depth within range but x / y far beyond any sane scene: voxel indices must not overflow.
  core::PointCloud cloud = FromDepth(Tabletop(160, 120));
  for (size_t i = 0; i < cloud.xyz.size(); i += 3) {
    cloud.xyz[i].x = (i % 2 == 0) ? 3e38f : -3e38f;
    cloud.xyz[i].y = (i % 5 == 0) ? 1e20f : cloud.xyz[i].y;
  }
  ExpectConsistent(cloud, Segment(cloud));
}

TEST(AdversarialFrames, TinyImages) {
  for (const int size : {1, 2}) {
    for (const uint16_t mm : {uint16_t{0}, uint16_t{1000}}) {
      SCOPED_TRACE(::testing::Message() << size << "x" << size << " at " << mm << " mm");
      const core::PointCloud cloud = FromDepth(core::DepthImage(size, size, mm));
      const SegmentationResult result = Segment(cloud);
      ExpectConsistent(cloud, result);
      EXPECT_EQ(result.num_valid_points, mm == 0 ? 0u : static_cast<uint32_t>(size * size));
    }
  }
}

TEST(AdversarialFrames, SingleRowAndColumn) {
  for (const auto& [w, h] : {std::pair{640, 1}, std::pair{1, 480}}) {
    SCOPED_TRACE(::testing::Message() << w << "x" << h);
    const core::PointCloud cloud = FromDepth(Tabletop(w, h));
    ExpectConsistent(cloud, Segment(cloud));
  }
}

TEST(AdversarialFrames, EveryPixelAtTheSamePoint) {
  core::PointCloud cloud;
  cloud.width = 640;
  cloud.height = 480;
  cloud.xyz.assign(640u * 480u, core::Vec3f{0.05f, -0.02f, 1.0f});
  const SegmentationResult result = Segment(cloud);
  ExpectConsistent(cloud, result);
  EXPECT_EQ(result.num_valid_points, 640u * 480u);
}

TEST(AdversarialFrames, CheckerboardOfValidAndInvalid) {
  core::DepthImage depth = Tabletop(640, 480);
  for (int v = 0; v < depth.height; ++v) {
    for (int u = 0; u < depth.width; ++u) {
      if ((u + v) % 2 == 1) depth.at(u, v) = 0;
    }
  }
  const core::PointCloud cloud = FromDepth(depth);
  const SegmentationResult result = Segment(cloud);
  ExpectConsistent(cloud, result);
  EXPECT_EQ(result.num_valid_points, 640u * 480u / 2);
}

TEST(AdversarialFrames, TabletopSanity) {
  // The reference frame of this file: a plane with two boxes gives at least one object.
  const core::PointCloud cloud = FromDepth(Tabletop(640, 480));
  const SegmentationResult result = Segment(cloud);
  ExpectConsistent(cloud, result);
  EXPECT_GE(result.objects.size(), 1u);
  EXPECT_GE(result.planes.size(), 1u);
}

TEST(AdversarialFrames, ReuseAfterAdversarialFramesMatchesFreshSegmenter) {
  // Buffers kept between calls must not leak state from one frame into the next.
  const core::PointCloud tabletop = FromDepth(Tabletop(320, 240));
  const SegmentationResult fresh = Segment(tabletop);
  Segmenter segmenter(SegmenterParams{});
  SegmentationResult result;
  const core::PointCloud frames[] = {FromDepth(core::DepthImage(2, 2, 1000)),
                                     FromDepth(core::DepthImage(640, 480, 0)),
                                     FromDepth(core::DepthImage(320, 240, 1200)), tabletop};
  for (const core::PointCloud& frame : frames) {
    segmenter.Process(frame, IntrinsicsFor(frame), &result);
    ExpectConsistent(frame, result);
  }
  EXPECT_EQ(result.labels.data, fresh.labels.data);
  EXPECT_EQ(result.objects.size(), fresh.objects.size());
  EXPECT_EQ(result.planes.size(), fresh.planes.size());
}

TEST(AdversarialFrames, ThreadPoolGivesIdenticalLabels) {
  core::ThreadPool pool(3);
  std::mt19937 rng(4242);
  core::DepthImage noisy = Tabletop(320, 240);
  for (uint16_t& d : noisy.data) {
    if (rng() % 5 == 0) d = static_cast<uint16_t>(300 + rng() % 2700);
  }
  for (const core::DepthImage& depth : {Tabletop(320, 240), noisy}) {
    const core::PointCloud cloud = FromDepth(depth);
    Segmenter pooled(SegmenterParams{}, &pool);
    SegmentationResult result;
    pooled.Process(cloud, IntrinsicsFor(cloud), &result);
    ExpectConsistent(cloud, result);
    EXPECT_EQ(result.labels.data, Segment(cloud).labels.data);
  }
}

TEST(AdversarialFrames, Frame4KFinishesWithBoundedMemory) {
  const core::PointCloud cloud = FromDepth(Tabletop(3840, 2160));
  const SegmentationResult result = Segment(cloud);
  ExpectConsistent(cloud, result);
  EXPECT_EQ(result.num_valid_points, 3840u * 2160u);
  EXPECT_GE(result.objects.size(), 1u);
  EXPECT_GE(result.planes.size(), 1u);

  const double peak_mib = PeakRssMib();
  RecordProperty("peak_rss_mib", static_cast<int>(peak_mib));
  std::printf("peak RSS after the 4K frame: %.0f MiB, %zu objects, %zu planes\n", peak_mib,
              result.objects.size(), result.planes.size());
  EXPECT_LT(peak_mib, 3072.0);
}

}  // namespace
}  // namespace clutterseg::pipeline
