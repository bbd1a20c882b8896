#pragma once

// Deterministic test frames and ONI files shared by the drivers tests.

#include <cstdint>
#include <string>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/types.h"
#include "clutterseg/drivers/oni/oni_writer.h"

namespace clutterseg::drivers::testutil {

inline constexpr int64_t kFramePeriodUs = 33333;

/// Depth of pixel (u, v) in frame `i`: distinct per pixel and frame, 0 on a few pixels.
inline uint16_t TestDepth(int u, int v, int i) {
  if ((u + v + i) % 97 == 0) return 0;
  return static_cast<uint16_t>(400 + (u * 7 + v * 13 + i * 31) % 5000);
}

inline core::Rgb8 TestColor(int u, int v, int i) {
  return core::Rgb8{static_cast<uint8_t>(u + i), static_cast<uint8_t>(v * 3),
                    static_cast<uint8_t>(i * 17 + u / 4)};
}

inline void MakeTestFrame(int w, int h, int i, core::DepthImage* depth, core::ColorImage* color) {
  depth->Reset(w, h);
  color->Reset(w, h);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      depth->at(u, v) = TestDepth(u, v, i);
      color->at(u, v) = TestColor(u, v, i);
    }
  }
}

/// Writes `frames` test frames of w x h at 30 fps timestamps (i * 33333 us).
inline void WriteTestOni(const std::string& path, int frames, bool with_color, int w = 640,
                         int h = 480, const core::CameraIntrinsics& k = {}) {
  OniWriter writer;
  writer.Open(path, w, h, 30, k, with_color);
  core::DepthImage depth;
  core::ColorImage color;
  for (int i = 0; i < frames; ++i) {
    MakeTestFrame(w, h, i, &depth, &color);
    writer.WriteFrame(depth, with_color ? &color : nullptr, i * kFramePeriodUs);
  }
  writer.Close();
}

/// Number of pixels of `depth` that differ from test frame `i`.
inline int CountDepthMismatches(const core::DepthImage& depth, int i) {
  int bad = 0;
  for (int v = 0; v < depth.height; ++v) {
    for (int u = 0; u < depth.width; ++u) bad += depth.at(u, v) != TestDepth(u, v, i) ? 1 : 0;
  }
  return bad;
}

inline int CountColorMismatches(const core::ColorImage& color, int i) {
  int bad = 0;
  for (int v = 0; v < color.height; ++v) {
    for (int u = 0; u < color.width; ++u) {
      const core::Rgb8 c = color.at(u, v);
      const core::Rgb8 e = TestColor(u, v, i);
      bad += (c.r != e.r || c.g != e.g || c.b != e.b) ? 1 : 0;
    }
  }
  return bad;
}

}  // namespace clutterseg::drivers::testutil
