#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/types.h"

namespace clutterseg::drivers {

/// Writes an ONI recording ("NI10", version 1.0.1.0) that the stock OpenNI2 OniFile driver
/// plays back: a "Depth" node (DEPTH_1_MM, 16-bit, codec NONE) and optionally an "Image" node
/// (RGB888, codec NONE) holding colour registered to depth. Every property OniFile needs is
/// written (xnMapOutputMode, xnCropping, oniPixelFormat, xnFOV, oniRequiredFrameSize,
/// xnDeviceMaxDepth, xnMirror), followed at Close() by per-node seek tables, the patched
/// NODE_ADDED records and END.
///
/// The file stores only a field of view, so a reader recovers fx = W / (2 tan(hfov / 2)) and
/// fy = H / (2 tan(vfov / 2)); the principal point is not representable (OpenNI2 assumes the
/// image centre).
///
/// Thread-safety: none; use one writer from one thread.
class OniWriter {
 public:
  OniWriter();
  /// Finalizes an open file (as Close()) but never throws; errors are printed to stderr.
  ~OniWriter();
  OniWriter(const OniWriter&) = delete;
  OniWriter& operator=(const OniWriter&) = delete;

  /// Creates `path` (truncating it) and writes the header, nodes and properties.
  /// `width` x `height` is the depth (and colour) resolution, `fps` the nominal frame rate
  /// recorded in xnMapOutputMode, `intrinsics` gives the field of view (only fx, fy and the
  /// resolution are used). @throws std::runtime_error naming the file on bad arguments or
  /// I/O failure, or when a file is already open.
  void Open(const std::string& path, int width, int height, int fps,
            const core::CameraIntrinsics& intrinsics, bool with_color);

  /// Appends one frame: depth in millimetres of the opened size, and colour of the same size
  /// when the file was opened with colour (`color` must then be non-null; it is ignored
  /// otherwise). `timestamp_us` must be >= 0 and not smaller than the previous one.
  /// @throws std::runtime_error naming the file on a size mismatch or I/O failure.
  void WriteFrame(const core::DepthImage& depth, const core::ColorImage* color,
                  int64_t timestamp_us);

  /// Appends a depth frame without its colour in a file opened with colour: what a live
  /// recording holds when the colour camera dropped a frame. As openni::Recorder does, each
  /// stream numbers its own frames 1, 2, ..., so the colour ids fall behind the depth ids
  /// from here on. Same requirements and errors as WriteFrame().
  void WriteDepthOnlyFrame(const core::DepthImage& depth, int64_t timestamp_us);

  /// Writes the seek tables, NODE_REMOVED and END records, patches the NODE_ADDED records
  /// and the file header, and closes the file. Does nothing when no file is open.
  /// @throws std::runtime_error naming the file on I/O failure (the file is closed anyway).
  void Close();

  bool is_open() const;
  /// Frames written since Open().
  int frames_written() const;
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::drivers
