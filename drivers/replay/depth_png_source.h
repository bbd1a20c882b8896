#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/frame_source.h"

namespace clutterseg::drivers {

/// Options of DepthPngSource.
struct DepthPngSourceOptions {
  /// Directory holding 16-bit depth PNGs, in one of two layouts:
  ///  - flat: files whose name contains "depth" (e.g. 000001-depth.png), colour beside them
  ///    with "depth" replaced by "color", "rgb" or "image" (000001-color.png);
  ///  - split: depth/NAME.png with colour in color/, rgb/, image/ or image_color/NAME.png.
  std::string directory;
  /// Intrinsics JSON (see io::ReadIntrinsicsJson). "" = the *.json file of `directory` when
  /// there is exactly one, `intrinsics` when there is none; two or more make Open() throw
  /// naming them (choose one here).
  std::string intrinsics_json;
  core::CameraIntrinsics intrinsics;  ///< used when no JSON is given or found
  /// Millimetres per PNG value: 1 for millimetre PNGs (Kinect / Xtion / RealSense exports,
  /// OSD, UCN), 0.2 for TUM RGB-D (value / 5000 = metres). A wrong scale does not fail any
  /// read: it moves every point out of the segmenter's depth range.
  double depth_scale_to_mm{1.0};
  bool color{true};  ///< load the colour PNGs when present
  bool loop{false};
  /// Frame k gets utime = k * frame_period_us (k counts across loops).
  int64_t frame_period_us{33333};
  std::string camera_name{"camera"};
  core::FrameLimits limits;  ///< larger PNGs are skipped (SkipReason::kTooLarge)

  /// @throws std::invalid_argument naming the key and value when an option is out of range.
  void ValidateOrThrow() const;
};

/// A core::FrameSource over a directory of depth PNGs (+ optional colour PNGs), read in
/// natural file-name order. Intrinsics given for another resolution of the same aspect
/// ratio are scaled to the images'.
///
/// A depth PNG that cannot be read (corrupt, not 16-bit grey, beyond `limits`) or whose size
/// has another aspect ratio than the intrinsics is skipped: Read() goes on with the next
/// frame and report() counts it with its reason and file name. A colour PNG that cannot be
/// read or is not of the depth's size is left out: the depth is delivered alone (counted in
/// SourceReport::frames_without_color). Frames whose depth is 0 everywhere are counted as
/// empty. Thread-safety: as core::FrameSource.
class DepthPngSource final : public core::FrameSource {
 public:
  /// @throws std::invalid_argument when `options` are invalid.
  explicit DepthPngSource(const DepthPngSourceOptions& options);

  /// Lists the frames and reads the intrinsics. @throws std::runtime_error naming the
  /// directory or files when there are no depth PNGs, the intrinsics cannot be read, or the
  /// directory holds several *.json files and `intrinsics_json` does not choose one.
  void Open() override;
  /// Reads the next readable frame, skipping and counting the others. kEndOfStream after the
  /// last one; kError only when a looping directory has no readable frame at all.
  core::ReadStatus Read(int timeout_ms, core::RgbdFrame* frame) override;
  void Close() override;
  bool IsLive() const override { return false; }
  std::string Describe() const override;
  std::string last_error() const override { return error_; }
  /// See core::FrameSource::report(); frames_in_source is the number of depth PNGs.
  core::SourceReport report() const override { return counters_.Snapshot(); }

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
  core::SourceCounters counters_;
};

}  // namespace clutterseg::drivers
