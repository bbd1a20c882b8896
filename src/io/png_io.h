#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"

struct libdeflate_compressor;  // <libdeflate.h>

namespace clutterseg::io {

// All functions here are thread-safe (no shared state) and name the file in every error.
// The readers check the size a PNG declares against `limits` (core::FrameLimits: width,
// height, pixels and bytes of the decoded image) and against what the file could decompress
// to before any image buffer is allocated; the writers refuse images the readers would
// refuse under the same limits.

/// Reads a 16-bit single-channel PNG of depth values. Values are multiplied by `scale_to_mm`
/// (1 for millimetre PNGs, 0.2 for TUM's value/5000 m), rounded and clamped to 65535.
/// @throws std::runtime_error naming the file when it is not a 16-bit grey PNG (8-bit and
/// colour PNGs are refused) or is corrupt. @throws std::invalid_argument when `scale_to_mm`
/// is not a positive finite number.
core::DepthImage ReadDepthPng(const std::string& path, double scale_to_mm = 1.0,
                              const core::FrameLimits& limits = {});

/// Reads a colour PNG as 8-bit RGB: RGB and RGBA (alpha dropped), grey (replicated) and
/// palette images are expanded, 16-bit channels reduced to 8 bits.
/// @throws std::runtime_error naming the file on error.
core::ColorImage ReadColorPng(const std::string& path, const core::FrameLimits& limits = {});

/// Writes an 8-bit RGB PNG, favouring speed over size (libdeflate level 1, Sub filter: about
/// 4.5 ms and 390 kB for a 640x480 frame on the 2-core reference machine, against 17 ms and
/// 410 kB for zlib's level 1). Makes a PngWriter for the one call: use a PngWriter to write
/// many.
/// A regular file is written under a temporary name beside `path` (`path`.tmp.PID.N) and
/// renamed to `path` once whole, so `path` is never a truncated PNG; on failure the temporary
/// file is removed and an existing `path` is left as it was. A device (/dev/null, /dev/full)
/// is written directly.
/// @throws std::runtime_error naming the file when the image exceeds `limits` or on I/O
/// failure (every write and the close are checked: a full disk is an error).
void WriteColorPng(const std::string& path, const core::ColorImage& image,
                   const core::FrameLimits& limits = {});

/// Writes a 16-bit grey PNG (e.g. depth in mm), big-endian as PNG requires; same speed-first
/// settings and errors as WriteColorPng.
void WriteDepthPng(const std::string& path, const core::DepthImage& image,
                   const core::FrameLimits& limits = {});

/// Writes PNGs one after another, keeping its compressor and its row, stream and file buffers
/// between them, so that a stream of frames allocates (and faults in) no fresh memory after
/// the first. Each file is written with one fwrite. Output and errors as WriteColorPng /
/// WriteDepthPng.
///
/// Thread-safety: one call at a time per object.
class PngWriter {
 public:
  /// @throws std::bad_alloc when the compressor cannot be allocated.
  PngWriter();
  ~PngWriter();
  PngWriter(const PngWriter&) = delete;
  PngWriter& operator=(const PngWriter&) = delete;

  void WriteColor(const std::string& path, const core::ColorImage& image,
                  const core::FrameLimits& limits = {});
  void WriteDepth(const std::string& path, const core::DepthImage& image,
                  const core::FrameLimits& limits = {});

 private:
  // Compresses filtered_ and writes the file.
  void Finish(const std::string& path, int width, int height, int bit_depth, int color_type);

  libdeflate_compressor* compressor_;
  std::vector<uint8_t> row_;       // one row, unfiltered, in PNG byte order
  std::vector<uint8_t> filtered_;  // per row: the filter type, then the filtered bytes
  std::vector<uint8_t> stream_;    // the zlib stream
  std::vector<uint8_t> file_;      // the whole file
};

/// Reads intrinsics from a small JSON file with keys fx, fy, cx, cy and optionally width,
/// height (640x480 when absent). Also accepted: the members of a nested {"camera": {...}};
/// cx/cy spelled x_offset/y_offset or ppx/ppy and width/height spelled img_width/img_height
/// (UCN); a 3x3 camera matrix under "intrinsic_matrix" or "K", as 9 numbers row- or
/// column-major (Open3D/TUM) or as 3 rows. Files over 1 MiB, JSON that is not RFC 8259 (UTF-8,
/// no comments), a key twice in one object and nesting deeper than 64 levels are refused.
/// @throws std::runtime_error naming the file and the key or JSON position at fault, also
/// when the values fail CameraIntrinsics::ValidateOrThrow().
core::CameraIntrinsics ReadIntrinsicsJson(const std::string& path);

/// Reads a depth PNG plus intrinsics into an organized cloud (metres, camera frame) with
/// core::DepthToPointCloud, with colour when `color_png` is non-empty.
/// @throws std::runtime_error naming the file when a read fails or when the depth image, the
/// intrinsics and the colour image disagree in size.
core::PointCloud ReadDepthPngCloud(const std::string& depth_png,
                                   const core::CameraIntrinsics& intrinsics,
                                   const std::string& color_png = "", double scale_to_mm = 1.0,
                                   const core::FrameLimits& limits = {});

}  // namespace clutterseg::io
