#include "clutterseg/pipeline/decimation.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "clutterseg/core/param_check.h"

namespace clutterseg::pipeline {

namespace {

constexpr uint32_t kMissing = 0xffffffffu;

// A block's pixels as keys (depth << 4 | position in the block), a missing depth as the
// largest key, so that ordering the keys orders the depths and keeps block order for equal
// ones. Returns the position of the pixel of lower-median valid depth, -1 when none is valid.
inline int MedianPosition(uint32_t* keys, int count, int valid) {
  if (valid == 0) return -1;
  const int k = (valid - 1) / 2;
  std::nth_element(keys, keys + k, keys + count);
  return static_cast<int>(keys[k] & 15u);
}

// Writes block (u, v)'s pixel: the one at `from` (its colour too), or no depth.
inline void Emit(size_t k, size_t from, bool valid, bool with_color, core::DepthImage* depth,
                 core::ColorImage* color) {
  if (with_color) color->data[k] = color->data[from];
  depth->data[k] = valid ? depth->data[from] : uint16_t{0};
}

// Factor 2, the common case: a sorting network of four keys on registers.
void DecimateByTwo(int w, int h, bool with_color, core::DepthImage* depth,
                   core::ColorImage* color) {
  const size_t stride = static_cast<size_t>(depth->width);
  for (int v = 0; v < h; ++v) {
    const size_t row = static_cast<size_t>(v) * 2 * stride;
    const uint16_t* top = depth->data.data() + row;
    const uint16_t* bottom = top + stride;
    for (int u = 0; u < w; ++u) {
      const uint32_t d0 = top[2 * u], d1 = top[2 * u + 1], d2 = bottom[2 * u],
                     d3 = bottom[2 * u + 1];
      // A missing depth's key has every bit set (no branch: holes are scattered).
      uint32_t k0 = d0 << 4 | (0u - (d0 == 0));
      uint32_t k1 = d1 << 4 | 1u | (0u - (d1 == 0));
      uint32_t k2 = d2 << 4 | 2u | (0u - (d2 == 0));
      uint32_t k3 = d3 << 4 | 3u | (0u - (d3 == 0));
      const int valid = (d0 != 0) + (d1 != 0) + (d2 != 0) + (d3 != 0);
      const auto cs = [](uint32_t& a, uint32_t& b) {
        const uint32_t lo = std::min(a, b);
        b = std::max(a, b);
        a = lo;
      };
      cs(k0, k1);
      cs(k2, k3);
      cs(k0, k2);
      cs(k1, k3);
      cs(k1, k2);
      // The lower median of `valid` keys: the first for 1 or 2, the second for 3 or 4.
      // (No depth: the block's first pixel, for its colour.)
      const uint32_t pos = valid == 0 ? 0u : (valid >= 3 ? k1 : k0) & 3u;
      const size_t first = row + 2 * static_cast<size_t>(u);
      Emit(static_cast<size_t>(v) * w + u, first + (pos >> 1) * stride + (pos & 1u), valid > 0,
           with_color, depth, color);
    }
  }
}

// Any factor up to kMaxDecimation: the keys of each block, partially ordered.
void DecimateByN(int factor, int w, int h, bool with_color, core::DepthImage* depth,
                 core::ColorImage* color) {
  std::array<uint32_t, kMaxDecimation * kMaxDecimation> keys{};
  const size_t stride = static_cast<size_t>(depth->width);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t first = (static_cast<size_t>(v) * stride + u) * factor;
      int valid = 0;
      for (int dv = 0; dv < factor; ++dv) {
        for (int du = 0; du < factor; ++du) {
          const uint16_t d = depth->data[first + dv * stride + du];
          const int pos = dv * factor + du;
          keys[pos] = d == 0 ? kMissing : (uint32_t{d} << 4 | static_cast<uint32_t>(pos));
          valid += d != 0;
        }
      }
      const int pos = MedianPosition(keys.data(), factor * factor, valid);
      const size_t from = pos < 0 ? first : first + (pos / factor) * stride + pos % factor;
      Emit(static_cast<size_t>(v) * w + u, from, pos >= 0, with_color, depth, color);
    }
  }
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
  if (factor == 2) {
    DecimateByTwo(w, h, with_color, &depth, &color);
  } else {
    DecimateByN(factor, w, h, with_color, &depth, &color);
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
  params.partition.min_pixels = std::max(1, (params.partition.min_pixels + area / 2) / area);
  return params;
}

}  // namespace clutterseg::pipeline
