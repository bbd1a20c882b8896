#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace clutterseg::core {

/// A 3-D point or vector in metres, camera frame (x right, y down, z forward).
/// Plain and 12 bytes so that arrays of it map onto Eigen (`Eigen::Map<Matrix3Xf>`).
struct Vec3f {
  float x{0.f};
  float y{0.f};
  float z{0.f};
};

/// The value stored for an invalid point.
inline constexpr float kInvalidDepth = std::numeric_limits<float>::quiet_NaN();

/// True when all three coordinates are finite.
inline bool IsValid(const Vec3f& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

/// 8-bit RGB colour.
struct Rgb8 {
  uint8_t r{0};
  uint8_t g{0};
  uint8_t b{0};
};

/// Packs a colour as PCL's `rgba` field does: 0xAARRGGBB.
inline uint32_t PackRgba(Rgb8 c, uint8_t a = 255) {
  return (uint32_t{a} << 24) | (uint32_t{c.r} << 16) | (uint32_t{c.g} << 8) | uint32_t{c.b};
}

/// Unpacks 0xAARRGGBB.
inline Rgb8 UnpackRgba(uint32_t v) {
  return Rgb8{static_cast<uint8_t>((v >> 16) & 0xff), static_cast<uint8_t>((v >> 8) & 0xff),
              static_cast<uint8_t>(v & 0xff)};
}

/// A dense row-major image: pixel (u, v) is `data[v * width + u]`.
template <typename T>
struct Image {
  int width{0};
  int height{0};
  std::vector<T> data;

  Image() = default;
  Image(int w, int h, T fill = T{}) : width(w), height(h), data(static_cast<size_t>(w) * h, fill) {}

  /// Resizes (reusing capacity) and fills every pixel with `fill`.
  void Reset(int w, int h, T fill = T{}) {
    width = w;
    height = h;
    data.assign(static_cast<size_t>(w) * h, fill);
  }
  size_t size() const { return data.size(); }
  bool empty() const { return data.empty(); }
  T& at(int u, int v) { return data[static_cast<size_t>(v) * width + u]; }
  const T& at(int u, int v) const { return data[static_cast<size_t>(v) * width + u]; }
};

/// Depth in millimetres, 0 = no measurement (the OpenNI2 DEPTH_1_MM format).
using DepthImage = Image<uint16_t>;
/// Registered colour image.
using ColorImage = Image<Rgb8>;
/// Per-pixel segment label; 0 = background / no object.
using LabelImage = Image<uint32_t>;

}  // namespace clutterseg::core
