#include "clutterseg/pipeline/decimation.h"

#include <algorithm>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "tests/testing/expect_invalid_argument.h"

namespace clutterseg::pipeline {
namespace {

// A frame of w x h whose colour encodes each pixel's position (r = u, g = v).
core::RgbdFrame Frame(int w, int h, const std::vector<uint16_t>& depth) {
  core::RgbdFrame f;
  f.depth.Reset(w, h);
  f.depth.data = depth;
  f.color.Reset(w, h);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      f.color.at(u, v) = core::Rgb8{static_cast<uint8_t>(u), static_cast<uint8_t>(v), 7};
    }
  }
  f.intrinsics.width = w;
  f.intrinsics.height = h;
  f.intrinsics.fx = 500.0;
  f.intrinsics.fy = 480.0;
  f.intrinsics.cx = 2.5;
  f.intrinsics.cy = 1.5;
  return f;
}

TEST(DecimateFrame, EachBlockKeepsItsPixelOfMedianValidDepthWithItsColour) {
  // Four 2x2 blocks in a 5x4 image (the fifth column is left out):
  //  block (0,0): 1000 1200 / 1100 0     -> valid {1000, 1100, 1200}: median 1100 at (0,1)
  //  block (1,0): 900 2000 / 2100 950    -> even count: lower median 950 at (3,1)
  //  block (0,1): 0 0 / 0 0              -> no depth
  //  block (1,1): 800 800 / 800 3000     -> equal depths keep block order: the second, (3,2)
  const std::vector<uint16_t> depth = {1000, 1200, 900,  2000, 5,  //
                                       1100, 0,    2100, 950,  5,  //
                                       0,    0,    800,  800,  5,  //
                                       0,    0,    800,  3000, 5};
  core::RgbdFrame f = Frame(5, 4, depth);
  const size_t capacity = f.depth.data.capacity();
  DecimateFrame(2, &f);
  ASSERT_EQ(f.depth.width, 2);
  ASSERT_EQ(f.depth.height, 2);
  ASSERT_EQ(f.color.width, 2);
  ASSERT_EQ(f.color.height, 2);
  EXPECT_EQ(f.depth.data, (std::vector<uint16_t>{1100, 950, 0, 800}));
  const auto at = [&](int i) { return std::vector<int>{f.color.data[i].r, f.color.data[i].g}; };
  EXPECT_EQ(at(0), (std::vector<int>{0, 1}));
  EXPECT_EQ(at(1), (std::vector<int>{3, 1}));
  EXPECT_EQ(at(2), (std::vector<int>{0, 2}));  // no depth: the block's first pixel
  EXPECT_EQ(at(3), (std::vector<int>{3, 2}));
  EXPECT_EQ(f.depth.data.capacity(), capacity);  // no reallocation
}

TEST(DecimateFrame, EveryFactorPicksTheLowerMedianOfEachBlock) {
  // Random depths with holes (blocks of every number of valid pixels, equal depths) against
  // the definition: the block's valid pixels ordered by depth, then block order.
  std::mt19937 rng(7);
  for (int factor = 2; factor <= kMaxDecimation; ++factor) {
    const int w = 13 * factor + 1, h = 11 * factor;
    std::vector<uint16_t> depth(static_cast<size_t>(w) * h);
    for (uint16_t& d : depth) d = rng() % 3 == 0 ? 0 : static_cast<uint16_t>(1000 + rng() % 4);
    core::RgbdFrame f = Frame(w, h, depth);
    DecimateFrame(factor, &f);
    ASSERT_EQ(f.depth.width, w / factor);
    for (int v = 0; v < h / factor; ++v) {
      for (int u = 0; u < w / factor; ++u) {
        std::vector<std::pair<uint16_t, int>> block;  // (depth, position in the block)
        for (int dv = 0; dv < factor; ++dv) {
          for (int du = 0; du < factor; ++du) {
            const uint16_t d = depth[static_cast<size_t>(v * factor + dv) * w + u * factor + du];
            if (d != 0) block.emplace_back(d, dv * factor + du);
          }
        }
        std::sort(block.begin(), block.end());
        const int pos = block.empty() ? 0 : block[(block.size() - 1) / 2].second;
        const size_t k = static_cast<size_t>(v) * f.depth.width + u;
        EXPECT_EQ(f.depth.data[k], block.empty() ? 0 : block[(block.size() - 1) / 2].first)
            << "factor " << factor << " block " << u << "," << v;
        EXPECT_EQ(f.color.data[k].r, u * factor + pos % factor) << "factor " << factor;
        EXPECT_EQ(f.color.data[k].g, v * factor + pos / factor) << "factor " << factor;
      }
    }
  }
}

TEST(DecimateFrame, BlockCentresBackProjectAlongTheSameRays) {
  core::RgbdFrame f = Frame(12, 9, std::vector<uint16_t>(12 * 9, 1000));
  const core::CameraIntrinsics k = f.intrinsics;
  DecimateFrame(3, &f);
  const core::CameraIntrinsics& d = f.intrinsics;
  EXPECT_EQ(d.width, 4);
  EXPECT_EQ(d.height, 3);
  EXPECT_DOUBLE_EQ(d.fx, k.fx / 3);
  EXPECT_DOUBLE_EQ(d.fy, k.fy / 3);
  // Pixel (u', v') of the reduced image is the centre of block u' (full-resolution pixels
  // 3u' .. 3u' + 2, centre 3u' + 1): the ray x/z = (u - cx) / fx is the same.
  for (int u = 0; u < d.width; ++u) {
    EXPECT_NEAR((u - d.cx) / d.fx, (3 * u + 1 - k.cx) / k.fx, 1e-12) << u;
  }
  for (int v = 0; v < d.height; ++v) {
    EXPECT_NEAR((v - d.cy) / d.fy, (3 * v + 1 - k.cy) / k.fy, 1e-12) << v;
  }
}

TEST(DecimateFrame, FactorOneCloudsAndFramesWithoutColourOrDepth) {
  const std::vector<uint16_t> depth = {1000, 1001, 1002, 1003};
  core::RgbdFrame f = Frame(2, 2, depth);
  DecimateFrame(1, &f);
  EXPECT_EQ(f.depth.data, depth);
  EXPECT_EQ(f.intrinsics.fx, 500.0);

  // A frame carrying the source's own cloud is segmented as it is.
  f.cloud.width = 4;
  f.cloud.height = 1;
  f.cloud.xyz.resize(4);
  DecimateFrame(2, &f);
  EXPECT_EQ(f.depth.width, 2);
  EXPECT_EQ(f.intrinsics.fx, 500.0);

  // Depth without colour.
  core::RgbdFrame g = Frame(2, 2, depth);
  g.color.Reset(0, 0);
  DecimateFrame(2, &g);
  EXPECT_EQ(g.depth.data, (std::vector<uint16_t>{1001}));
  EXPECT_TRUE(g.color.empty());

  // No depth at all: nothing to do.
  core::RgbdFrame e;
  DecimateFrame(2, &e);
  EXPECT_TRUE(e.depth.empty());
}

TEST(DecimateFrame, RejectsAFactorOutOfRangeNamingTheKey) {
  core::RgbdFrame f = Frame(2, 2, std::vector<uint16_t>(4, 1000));
  testing::ExpectInvalidArgumentNaming([&] { DecimateFrame(0, &f); }, "camera.decimation");
  testing::ExpectInvalidArgumentNaming([&] { DecimateFrame(kMaxDecimation + 1, &f); },
                                       "camera.decimation");
  testing::ExpectInvalidArgumentNaming([&] { ForDecimatedFrames(SegmenterParams{}, 0); },
                                       "camera.decimation");
}

TEST(ForDecimatedFrames, DividesThePointCountsByTheFactorSquared) {
  SegmenterParams p;
  p.objects.min_object_points = 150;
  EXPECT_EQ(ForDecimatedFrames(p, 1).objects.min_object_points, 150);
  EXPECT_EQ(ForDecimatedFrames(p, 2).objects.min_object_points, 38);  // 37.5, rounded
  EXPECT_EQ(ForDecimatedFrames(p, 3).objects.min_object_points, 17);
  p.objects.min_object_points = 1;
  EXPECT_EQ(ForDecimatedFrames(p, 4).objects.min_object_points, 1);
  p.partition.min_pixels = 100;
  EXPECT_EQ(ForDecimatedFrames(p, 2).partition.min_pixels, 25);
  EXPECT_EQ(ForDecimatedFrames(p, 1).partition.min_pixels, 100);
  // Everything else stays.
  const SegmenterParams d;
  const SegmenterParams q = ForDecimatedFrames(d, 2);
  EXPECT_EQ(q.support.margin_px, d.support.margin_px);
  EXPECT_EQ(q.supervoxel.seed_resolution_m, d.supervoxel.seed_resolution_m);
  EXPECT_EQ(q.planes.min_patch_points, d.planes.min_patch_points);
  EXPECT_TRUE(q.temporal == d.temporal);
}

}  // namespace
}  // namespace clutterseg::pipeline
