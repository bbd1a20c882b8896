#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace clutterseg::core {

/// The one set of size limits of every frame reader and writer: PCD and PNG files, ONI
/// recordings and the frames OpenNI2 delivers, label_image_t messages. Each reader checks the
/// sizes a file or message *declares* against these limits before it allocates anything, and
/// each writer refuses what the readers would refuse, so whatever clutterseg writes it can
/// read back.
///
/// The defaults are sized for real RGB-D sensors (Kinect / Xtion 640x480, RealSense and Azure
/// Kinect up to 1280x720 / 1024x1024 depth, colour registered to depth at up to 4K): images
/// and organized clouds up to 4096 x 4096 pixels, clouds up to 4096 * 4096 points, and at
/// most 512 MiB in any one frame buffer (a 4096 x 4096 cloud of 32-byte points: x y z rgb,
/// a normal and a curvature). Raise them only for data that really is larger; the segmenter
/// needs several times a frame's size in working memory.
///
/// Thread-safety: a plain value; the const methods may be called from any thread.
struct FrameLimits {
  int max_width{4096};                         ///< pixels per row of an image or organized cloud
  int max_height{4096};                        ///< rows of an image or organized cloud
  uint64_t max_points{uint64_t{4096} * 4096};  ///< pixels of an image, points of any cloud
  uint64_t max_bytes{uint64_t{512} * 1024 * 1024};  ///< bytes of one frame buffer: a file,
                                                    ///< a record payload or decoded frame data

  /// Checks that the limits themselves are usable: width and height 1..65535, points
  /// 1..2^40, bytes 1 KiB..2^44.
  /// @throws std::invalid_argument naming `<section>.<field>` and the value.
  void ValidateOrThrow(std::string_view section = "limits") const;

  /// Why an image (or organized cloud) of `width` x `height` pixels of `bytes_per_pixel`
  /// bytes each must be refused, e.g. "16384x16384 px exceeds the frame limit of 4096x4096
  /// px"; std::nullopt when it is within the limits. Negative or zero sizes are refused too.
  /// O(1), never allocates unless it refuses.
  std::optional<std::string> CheckImage(int64_t width, int64_t height,
                                        uint64_t bytes_per_pixel) const;
  /// Same for a cloud of `points` points of `bytes_per_point` bytes each, organized or not
  /// (0 points are allowed: an empty cloud).
  std::optional<std::string> CheckPoints(uint64_t points, uint64_t bytes_per_point) const;
  /// Same for one buffer of `bytes` bytes (a file, a payload, decoded data).
  std::optional<std::string> CheckBytes(uint64_t bytes) const;
};

/// Thrown by the readers and writers when a declared size exceeds the FrameLimits (a subclass
/// of std::runtime_error, so callers that do not care catch it as any read error); the
/// message names the file and the limit. Frame sources count such frames as
/// SkipReason::kTooLarge.
class FrameTooLargeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace clutterseg::core
