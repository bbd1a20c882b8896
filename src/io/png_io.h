#pragma once

#include <string>

#include "core/camera_intrinsics.h"
#include "core/point_cloud.h"
#include "core/types.h"

namespace clutterseg::io {

/// Reads a 16-bit single-channel PNG of depth values. Values are multiplied by `scale_to_mm`
/// (1 for millimetre PNGs, 0.2 for TUM's value/5000 m) and rounded.
/// @throws std::runtime_error naming the file when it is not a 16-bit grey PNG or is corrupt.
core::DepthImage ReadDepthPng(const std::string& path, double scale_to_mm = 1.0);

/// Reads an 8-bit RGB or RGBA PNG (alpha dropped); grey PNGs are expanded.
/// @throws std::runtime_error naming the file on error.
core::ColorImage ReadColorPng(const std::string& path);

/// Writes an 8-bit RGB PNG. @throws std::runtime_error on I/O failure.
void WriteColorPng(const std::string& path, const core::ColorImage& image);

/// Writes a 16-bit grey PNG (e.g. depth in mm). @throws std::runtime_error on I/O failure.
void WriteDepthPng(const std::string& path, const core::DepthImage& image);

/// Reads intrinsics from a small JSON file with keys fx, fy, cx, cy and optionally width,
/// height (also accepts the nested {"camera": {...}} / "intrinsic_matrix" forms used by the
/// TUM and UCN data sets). @throws std::runtime_error naming the file and key.
core::CameraIntrinsics ReadIntrinsicsJson(const std::string& path);

/// Reads a depth PNG plus intrinsics into an organized cloud (with colour when `color_png`
/// is non-empty). @throws std::runtime_error on error.
core::PointCloud ReadDepthPngCloud(const std::string& depth_png,
                                   const core::CameraIntrinsics& intrinsics,
                                   const std::string& color_png = "", double scale_to_mm = 1.0);

}  // namespace clutterseg::io
