#include "clutterseg/pipeline/overlay.h"

#include <algorithm>
#include <cmath>

#include "clutterseg/core/text_and_color.h"

namespace clutterseg::pipeline {

core::Rgb8 LabelColor(uint32_t id) {
  if (id == 0) return core::Rgb8{0, 0, 0};
  // Golden-ratio hue steps give well separated colours for consecutive ids.
  return core::HsvToRgb(0.13 + 0.618033988749895 * id, (id % 3 == 0) ? 0.65 : 0.85,
                        (id % 2 == 0) ? 0.95 : 0.8);
}

void CloudToImage(const core::PointCloud& cloud, core::ColorImage* out) {
  const int w = cloud.width;
  const int h = std::max(cloud.height, 1);
  out->Reset(w, h);
  if (cloud.has_color()) {
    for (size_t i = 0; i < cloud.size(); ++i) {
      out->data[i] = core::IsValid(cloud.xyz[i]) ? core::UnpackRgba(cloud.rgba[i]) : core::Rgb8{};
    }
    return;
  }
  float zmin = 1e9f, zmax = 0.f;
  for (const core::Vec3f& p : cloud.xyz) {
    if (!core::IsValid(p)) continue;
    zmin = std::min(zmin, p.z);
    zmax = std::max(zmax, p.z);
  }
  const float range = std::max(zmax - zmin, 1e-3f);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const core::Vec3f& p = cloud.xyz[i];
    if (!core::IsValid(p)) continue;
    const auto g = static_cast<uint8_t>(230.f - 180.f * (p.z - zmin) / range);
    out->data[i] = core::Rgb8{g, g, g};
  }
}

void DepthToImage(const core::DepthImage& depth, core::ColorImage* out) {
  out->Reset(depth.width, depth.height);
  uint16_t dmin = UINT16_MAX, dmax = 0;
  for (const uint16_t d : depth.data) {
    if (d == 0) continue;
    dmin = std::min(dmin, d);
    dmax = std::max(dmax, d);
  }
  const float range = std::max(static_cast<float>(dmax) - static_cast<float>(dmin), 1.f);
  for (size_t i = 0; i < depth.data.size(); ++i) {
    const uint16_t d = depth.data[i];
    if (d == 0) continue;
    const auto g = static_cast<uint8_t>(230.f - 180.f * (static_cast<float>(d - dmin)) / range);
    out->data[i] = core::Rgb8{g, g, g};
  }
}

void RenderOverlay(const core::LabelImage& labels, const core::ColorImage* base,
                   core::ColorImage* out) {
  const int w = labels.width;
  const int h = labels.height;
  out->Reset(w, h);
  const bool have_base = base != nullptr && base->width == w && base->height == h;
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      const core::Rgb8 b = have_base ? base->data[i] : core::Rgb8{};
      const uint32_t l = labels.data[i];
      if (l == 0) {
        out->data[i] = core::Rgb8{static_cast<uint8_t>(b.r / 2), static_cast<uint8_t>(b.g / 2),
                                  static_cast<uint8_t>(b.b / 2)};
        continue;
      }
      const core::Rgb8 c = LabelColor(l);
      const bool border =
          (u > 0 && labels.data[i - 1] != l) || (u + 1 < w && labels.data[i + 1] != l) ||
          (v > 0 && labels.data[i - w] != l) || (v + 1 < h && labels.data[i + w] != l);
      if (border) {
        out->data[i] = c;
      } else {
        out->data[i] = core::Rgb8{static_cast<uint8_t>((c.r * 3 + b.r * 2) / 5),
                                  static_cast<uint8_t>((c.g * 3 + b.g * 2) / 5),
                                  static_cast<uint8_t>((c.b * 3 + b.b * 2) / 5)};
      }
    }
  }
}

}  // namespace clutterseg::pipeline
