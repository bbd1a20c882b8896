#pragma once

#include <string>

#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/point_cloud.h"

namespace clutterseg::io {

/// Limits of the PCD reader: the frame limits every reader and writer shares
/// (core::FrameLimits: width, height, points, bytes of the file and of its decoded data) plus
/// the longest header. Every size a header declares is checked against them before anything
/// is allocated; a file larger than `max_bytes` plus the header is refused before it is read.
struct ReadLimits : core::FrameLimits {
  size_t max_header_bytes{64u * 1024u};  ///< refuse headers longer than this
};

/// Reads a PCD v0.7 (or 0.6/0.5) file: organized or not, DATA ascii, binary or
/// binary_compressed (LZF), fields x y z plus optional rgb/rgba and label in any order; other
/// fields are skipped. Fills `xyz`, and `rgba` / `label` when present (`rgba` from a field
/// named `rgba`, or from packed `rgb`, which is reported with alpha 0xFF). Integer labels of
/// any size are converted to uint32. Little-endian data; `VIEWPOINT` is ignored.
/// Organized clouds (HEIGHT > 1) must fit `limits` as an image (WIDTH x HEIGHT), every cloud
/// as points (POINTS and the bytes of its records).
/// @throws std::runtime_error naming the file and what is wrong (malformed header, truncated
/// data, sizes beyond `limits`). Never allocates more than the file can justify.
core::PointCloud ReadPcd(const std::string& path, const ReadLimits& limits = {});

/// Same, from an in-memory buffer; `name` is used in error messages.
core::PointCloud ReadPcdFromMemory(const void* data, size_t size, const std::string& name,
                                   const ReadLimits& limits = {});

/// Same as ReadPcd, reusing the storage of `cloud` (one frame after another allocates
/// nothing once the buffers have grown). On error `cloud` holds unspecified contents.
/// Thread-safe for distinct `cloud`s; each thread keeps its file and decoding buffers (up to
/// 64 MiB each) for reuse.
void ReadPcd(const std::string& path, const ReadLimits& limits, core::PointCloud* cloud);

/// In-memory variant of the reusing ReadPcd.
void ReadPcdFromMemory(const void* data, size_t size, const std::string& name,
                       const ReadLimits& limits, core::PointCloud* cloud);

/// PCD DATA encodings that WritePcd can produce.
enum class PcdEncoding { kAscii, kBinary, kBinaryCompressed };

/// Writes `cloud` as PCD v0.7 with fields x y z rgba label (PCL's PointXYZRGBL layout; rgba
/// is 0xFF000000 and label 0 when the cloud has none). Organized clouds keep width/height.
/// A cloud the reader would refuse under `limits` (the same core::FrameLimits) is refused
/// before anything is written, so every file WritePcd writes, ReadPcd reads back.
/// @throws std::runtime_error naming the file when the cloud exceeds `limits` or the file
/// cannot be written completely (open, write, e.g. a full disk, or close failed).
void WritePcd(const std::string& path, const core::PointCloud& cloud,
              PcdEncoding encoding = PcdEncoding::kBinary, const core::FrameLimits& limits = {});

}  // namespace clutterseg::io
