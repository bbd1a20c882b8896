#include "clutterseg/pipeline/decimation.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "clutterseg/core/param_check.h"

namespace clutterseg::pipeline {

namespace {

// The index (into the frame) of the pixel of block (bu, bv) whose depth is the lower median
// of the block's valid depths; -1 when none is valid. Equal depths keep block order.
inline ptrdiff_t MedianPixel(const core::DepthImage& depth, int factor, int bu, int bv) {
  std::array<uint16_t, kMaxDecimation * kMaxDecimation> z{};
  std::array<ptrdiff_t, kMaxDecimation * kMaxDecimation> at{};
  int n = 0;
  for (int dv = 0; dv < factor; ++dv) {
    const ptrdiff_t row = static_cast<ptrdiff_t>(bv * factor + dv) * depth.width;
    for (int du = 0; du < factor; ++du) {
      const ptrdiff_t i = row + bu * factor + du;
      const uint16_t d = depth.data[static_cast<size_t>(i)];
      if (d == 0) continue;
      // Insertion: a few values, and stable for equal depths.
      int k = n++;
      while (k > 0 && z[k - 1] > d) {
        z[k] = z[k - 1];
        at[k] = at[k - 1];
        --k;
      }
      z[k] = d;
      at[k] = i;
    }
  }
  return n == 0 ? -1 : at[(n - 1) / 2];
}

}  // namespace

void DecimateFrame(int factor, core::RgbdFrame* frame) {
  core::ParamCheck("camera").InRange("decimation", factor, 1, kMaxDecimation, "");
  core::DepthImage& depth = frame->depth;
  if (factor == 1 || depth.empty() || !frame->cloud.empty()) return;
  const int w = depth.width / factor;
  const int h = depth.height / factor;
  core::ColorImage& color = frame->color;
  const bool with_color = color.width == depth.width && color.height == depth.height;
  // In place, row-major: output pixel k reads only input pixels at index >= k, and writing k
  // overwrites no input that a later output pixel reads (their blocks start after k).
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const ptrdiff_t i = MedianPixel(depth, factor, u, v);
      const ptrdiff_t first = static_cast<ptrdiff_t>(v * factor) * depth.width + u * factor;
      const size_t k = static_cast<size_t>(v) * w + u;
      const ptrdiff_t from = i < 0 ? first : i;
      if (with_color) color.data[k] = color.data[static_cast<size_t>(from)];
      depth.data[k] = i < 0 ? uint16_t{0} : depth.data[static_cast<size_t>(i)];
    }
  }
  depth.width = w;
  depth.height = h;
  depth.data.resize(static_cast<size_t>(w) * h);
  if (with_color) {
    color.width = w;
    color.height = h;
    color.data.resize(static_cast<size_t>(w) * h);
  }
  core::CameraIntrinsics& k = frame->intrinsics;
  const double f = static_cast<double>(factor);
  k.fx /= f;
  k.fy /= f;
  k.cx = (k.cx + 0.5) / f - 0.5;
  k.cy = (k.cy + 0.5) / f - 0.5;
  k.width = w;
  k.height = h;
}

SegmenterParams ForDecimatedFrames(SegmenterParams params, int factor) {
  core::ParamCheck("camera").InRange("decimation", factor, 1, kMaxDecimation, "");
  if (factor == 1) return params;
  const int area = factor * factor;
  params.objects.min_object_points =
      std::max(1, (params.objects.min_object_points + area / 2) / area);
  return params;
}

}  // namespace clutterseg::pipeline
