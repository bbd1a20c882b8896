#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/frame_source.h"

namespace clutterseg::drivers {

/// Options of DepthPngSource.
struct DepthPngSourceOptions {
  /// Directory holding 16-bit depth PNGs, in one of two layouts:
  ///  - flat: files whose name contains "depth" (e.g. 000001-depth.png), colour beside them
  ///    with "depth" replaced by "color", "rgb" or "image" (000001-color.png);
  ///  - split: depth/NAME.png with colour in color/, rgb/, image/ or image_color/NAME.png.
  std::string directory;
  /// Intrinsics JSON (see io::ReadIntrinsicsJson). "" = the only *.json file of `directory`
  /// if there is exactly one, else `intrinsics`.
  std::string intrinsics_json;
  core::CameraIntrinsics intrinsics;  ///< used when no JSON is given or found
  double depth_scale_to_mm{1.0};      ///< 1 for millimetre PNGs, 0.2 for TUM (value / 5000 m)
  bool color{true};                   ///< load the colour PNGs when present
  bool loop{false};
  /// Frame k gets utime = k * frame_period_us (k counts across loops).
  int64_t frame_period_us{33333};
  std::string camera_name{"camera"};

  /// @throws std::invalid_argument naming the key and value when an option is out of range.
  void ValidateOrThrow() const;
};

/// A core::FrameSource over a directory of depth PNGs (+ optional colour PNGs), read in
/// natural file-name order. Intrinsics given for another resolution are scaled to the
/// images'. Thread-safety: as core::FrameSource.
class DepthPngSource final : public core::FrameSource {
 public:
  /// @throws std::invalid_argument when `options` are invalid.
  explicit DepthPngSource(const DepthPngSourceOptions& options);

  /// Lists the frames and reads the intrinsics. @throws std::runtime_error naming the
  /// directory or file when there are no depth PNGs or the intrinsics cannot be read.
  void Open() override;
  /// Reads the next frame. A PNG that cannot be read, or colour of another size than the
  /// depth, gives kError naming the file; the next Read continues with the next frame.
  core::ReadStatus Read(int timeout_ms, core::RgbdFrame* frame) override;
  void Close() override;
  bool IsLive() const override { return false; }
  std::string Describe() const override;
  std::string last_error() const override { return error_; }

  struct Entry {
    std::string depth;
    std::string color;  ///< "" when there is none
  };
  const std::vector<Entry>& entries() const { return entries_; }
  const core::CameraIntrinsics& intrinsics() const { return intrinsics_; }

 private:
  const DepthPngSourceOptions options_;
  std::vector<Entry> entries_;
  std::string intrinsics_source_;
  core::CameraIntrinsics intrinsics_;
  size_t next_{0};
  uint64_t sequence_{0};
  bool open_{false};
  std::string error_;
};

}  // namespace clutterseg::drivers
