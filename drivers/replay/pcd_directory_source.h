#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/frame_source.h"
#include "clutterseg/core/point_cloud.h"

namespace clutterseg::drivers {

/// Options of PcdDirectorySource.
struct PcdDirectorySourceOptions {
  /// A directory of *.pcd files (read in natural order: "learn2" before "learn10") or one
  /// .pcd file.
  std::string path;
  /// true: fit the intrinsics to the first readable organized cloud (see
  /// EstimateIntrinsics); false: use `intrinsics`.
  bool estimate_intrinsics{true};
  core::CameraIntrinsics intrinsics;  ///< used when estimate_intrinsics is false
  bool loop{false};                   ///< start again after the last file
  /// PCD files carry no time: frame k gets utime = k * frame_period_us (k counts across loops).
  int64_t frame_period_us{33333};
  std::string camera_name{"camera"};  ///< copied into RgbdFrame::camera_name
  core::FrameLimits limits;           ///< larger files are skipped (SkipReason::kTooLarge)

  /// @throws std::invalid_argument naming the key and value when an option is out of range.
  void ValidateOrThrow() const;
};

/// Least-squares pinhole fit to an organized cloud: for every finite point with z > 0 at
/// pixel (u, v), u = fx * x / z + cx and v = fy * y / z + cy. Each axis is an independent
/// linear regression (two unknowns) over all finite points, solved in closed form in double
/// precision. `rms_px`, when non-null, receives the root-mean-square reprojection error.
/// @throws std::runtime_error when the cloud is not organized, has fewer than 16 finite
/// points, its points do not span at least two columns and two rows, or the fit gives
/// non-positive focal lengths.
core::CameraIntrinsics EstimateIntrinsics(const core::PointCloud& cloud, double* rms_px = nullptr);

/// Converts a cloud to a depth image (millimetres, rounded; 0 where invalid or z <= 0) and
/// colour (from rgba, empty when the cloud has none). Organized clouds map point (u, v) to
/// pixel (u, v); unorganized clouds are projected with `intrinsics` keeping the nearest point
/// per pixel. Reuses the buffers of `depth` and `color`.
void CloudToDepth(const core::PointCloud& cloud, const core::CameraIntrinsics& intrinsics,
                  core::DepthImage* depth, core::ColorImage* color);

/// A core::FrameSource replaying PCD files (e.g. the mOSD / OSD data sets): each frame carries
/// the file's cloud as it is (RgbdFrame::cloud, organized or not, so that the daemon segments
/// exactly what clutterseg-segment segments) and its depth and colour images (CloudToDepth),
/// for display and recording.
///
/// A file that cannot be read (truncated, corrupt, beyond `limits`) or whose organized size
/// has another aspect ratio than the intrinsics is skipped: Read() goes on with the next file
/// and report() counts it with its reason and the file's name. report() also counts frames
/// without a single finite point (SourceReport::frames_empty).
/// Thread-safety: as core::FrameSource.
class PcdDirectorySource final : public core::FrameSource {
 public:
  /// @throws std::invalid_argument when `options` are invalid.
  explicit PcdDirectorySource(const PcdDirectorySourceOptions& options);

  /// Lists the files and fixes the intrinsics (fitted to the first readable organized file,
  /// and checked with core::CameraIntrinsics::ValidateOrThrow).
  /// @throws std::runtime_error naming the path when there are no PCD files or no readable
  /// organized file gives plausible intrinsics.
  void Open() override;
  /// Reads the next readable file (the timeout is not needed: files are read synchronously),
  /// skipping and counting the others. kEndOfStream after the last file; kError only when a
  /// looping directory has no readable file at all.
  core::ReadStatus Read(int timeout_ms, core::RgbdFrame* frame) override;
  void Close() override;
  bool IsLive() const override { return false; }
  std::string Describe() const override;
  std::string last_error() const override { return error_; }
  /// See core::FrameSource::report(); frames_in_source is the number of .pcd files.
  core::SourceReport report() const override { return counters_.Snapshot(); }

  const std::vector<std::string>& files() const { return files_; }
  /// Intrinsics attached to the frames (valid after Open()).
  const core::CameraIntrinsics& intrinsics() const { return intrinsics_; }

 private:
  const PcdDirectorySourceOptions options_;
  std::vector<std::string> files_;
  size_t next_{0};
  uint64_t sequence_{0};
  bool open_{false};
  core::CameraIntrinsics intrinsics_;
  double fit_rms_px_{0.0};
  core::PointCloud cloud_;
  std::string error_;
  core::SourceCounters counters_;
};

namespace internal {
/// Sorts file names so that embedded numbers compare by value ("a2" < "a10").
void NaturalSort(std::vector<std::string>* names);
/// Why intrinsics for `k.width` x `k.height` cannot be scaled to a `width` x `height` frame
/// (another aspect ratio: another sensor mode or crop, not a resolution change), or "" when
/// they can.
std::string ScalingProblem(const core::CameraIntrinsics& k, int width, int height);
}  // namespace internal

}  // namespace clutterseg::drivers
