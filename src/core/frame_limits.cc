#include "clutterseg/core/frame_limits.h"

#include <limits>

#include "clutterseg/core/param_check.h"

namespace clutterseg::core {
namespace {

// a * b, or the largest uint64_t when the product overflows.
uint64_t SaturatingMul(uint64_t a, uint64_t b) {
  uint64_t r = 0;
  return __builtin_mul_overflow(a, b, &r) ? std::numeric_limits<uint64_t>::max() : r;
}

std::string Mib(uint64_t bytes) {
  const uint64_t mib = uint64_t{1} << 20;
  if (bytes % mib == 0) return std::to_string(bytes / mib) + " MiB";
  return std::to_string(bytes) + " bytes";
}

}  // namespace

void FrameLimits::ValidateOrThrow(std::string_view section) const {
  const ParamCheck check(section);
  check.InRange("max_width", max_width, 1, 65535, "px");
  check.InRange("max_height", max_height, 1, 65535, "px");
  check.InRange("max_points", max_points, uint64_t{1}, uint64_t{1} << 40, "points");
  check.InRange("max_bytes", max_bytes, uint64_t{1024}, uint64_t{1} << 44, "bytes");
}

std::optional<std::string> FrameLimits::CheckImage(int64_t width, int64_t height,
                                                   uint64_t bytes_per_pixel) const {
  const std::string size = std::to_string(width) + "x" + std::to_string(height) + " px";
  if (width <= 0 || height <= 0) return size + " is not an image size";
  if (width > max_width || height > max_height) {
    return size + " exceeds the frame limit of " + std::to_string(max_width) + "x" +
           std::to_string(max_height) + " px";
  }
  const uint64_t pixels =
      SaturatingMul(static_cast<uint64_t>(width), static_cast<uint64_t>(height));
  if (pixels > max_points) {
    return size + " exceeds the frame limit of " + std::to_string(max_points) + " pixels";
  }
  const uint64_t bytes = SaturatingMul(pixels, bytes_per_pixel);
  if (bytes > max_bytes) {
    return size + " at " + std::to_string(bytes_per_pixel) + " bytes per pixel (" +
           std::to_string(bytes) + " bytes) exceeds the frame limit of " + Mib(max_bytes);
  }
  return std::nullopt;
}

std::optional<std::string> FrameLimits::CheckPoints(uint64_t points,
                                                    uint64_t bytes_per_point) const {
  if (points > max_points) {
    return std::to_string(points) + " points exceed the frame limit of " +
           std::to_string(max_points) + " points";
  }
  const uint64_t bytes = SaturatingMul(points, bytes_per_point);
  if (bytes > max_bytes) {
    return std::to_string(points) + " points of " + std::to_string(bytes_per_point) + " bytes (" +
           std::to_string(bytes) + " bytes) exceed the frame limit of " + Mib(max_bytes);
  }
  return std::nullopt;
}

std::optional<std::string> FrameLimits::CheckBytes(uint64_t bytes) const {
  if (bytes > max_bytes) {
    return std::to_string(bytes) + " bytes exceed the frame limit of " + Mib(max_bytes);
  }
  return std::nullopt;
}

}  // namespace clutterseg::core
