#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/types.h"

namespace clutterseg::core {

class ThreadPool;

/// A point cloud in the camera frame, metres. Organized when `height > 1`: point (u, v) is
/// index `v * width + u`, and invalid pixels hold NaN coordinates. An unorganized cloud has
/// `height == 1`. `rgba` (0xAARRGGBB) and `label` are either empty or have one entry per point.
struct PointCloud {
  int width{0};
  int height{0};
  std::vector<Vec3f> xyz;
  std::vector<uint32_t> rgba;
  std::vector<uint32_t> label;

  size_t size() const { return xyz.size(); }
  bool empty() const { return xyz.empty(); }
  bool organized() const { return height > 1; }
  bool has_color() const { return !rgba.empty(); }
  bool has_label() const { return !label.empty(); }
  /// Number of points with finite coordinates. O(n).
  size_t CountValid() const;
};

/// A read-only view of point data laid out as in PointCloud (organized when `height > 1`,
/// point (u, v) at `v * width + u`, NaN = invalid; `rgba` empty or one 0xAARRGGBB per point):
/// what the segmenter reads, so that a caller's own memory (the Python module's numpy arrays)
/// is segmented without a copy. A PointCloud converts to it implicitly. The viewed memory must
/// outlive the view and must not change while it is read. Thread-safety: a plain value.
struct PointCloudView {
  int width{0};
  int height{0};
  std::span<const Vec3f> xyz;
  std::span<const uint32_t> rgba;

  PointCloudView() = default;
  // Implicit: every function taking a view takes a PointCloud as before.
  PointCloudView(const PointCloud& cloud)  // NOLINT(google-explicit-constructor)
      : width(cloud.width), height(cloud.height), xyz(cloud.xyz), rgba(cloud.rgba) {}

  size_t size() const { return xyz.size(); }
  bool empty() const { return xyz.empty(); }
  bool organized() const { return height > 1; }
  bool has_color() const { return !rgba.empty(); }
};

/// The intrinsics to segment `cloud` with: `intrinsics` scaled to the cloud's size
/// (CameraIntrinsics::Scaled, the same sensor at another resolution) when the cloud is
/// organized and its size differs, otherwise `intrinsics` unchanged (an unorganized cloud is
/// segmented without them; they only draw it). What clutterseg-segment and the Python module
/// pass to Segmenter::Process.
CameraIntrinsics IntrinsicsForCloud(const CameraIntrinsics& intrinsics,
                                    const PointCloudView& cloud);

/// Back-projects a depth image (millimetres, 0 = invalid) into an organized cloud, reusing
/// `cloud`'s storage. Colour is copied when `color` is non-null and has the depth's size.
/// Depth values outside [min_m, max_m] become invalid. Rows are split over `pool` when it is
/// non-null; the result does not depend on it. Returns the number of valid points.
size_t DepthToPointCloud(const DepthImage& depth, const CameraIntrinsics& intrinsics,
                         const ColorImage* color, PointCloud* cloud, float min_m = 0.f,
                         float max_m = 100.f, ThreadPool* pool = nullptr);

}  // namespace clutterseg::core
