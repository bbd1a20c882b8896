#pragma once

#include "clutterseg/core/frame.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::pipeline {

/// Largest decimation factor DecimateFrame takes.
inline constexpr int kMaxDecimation = 4;

/// Reduces a depth frame (and its registered colour) by `factor` in each direction, in place:
/// each factor x factor block of pixels becomes the one pixel of the block whose depth is the
/// median of the block's valid depths (the lower median of an even count; 0 when none is
/// valid), with that pixel's colour, so no depth is ever invented between two surfaces at an
/// edge. A 640x480 frame at factor 2 becomes 320x240 (columns and rows beyond the last whole
/// block are left out). The intrinsics are those of the reduced image: fx / factor,
/// fy / factor, and the principal point moved so that block centres back-project along the
/// same rays: cx' = (cx + 0.5) / factor - 0.5 (cy likewise).
///
/// Factor 1, a frame without depth or a frame carrying its own cloud (PCD sources, segmented
/// as they are) are left unchanged. No allocation: the images keep their capacity.
///
/// Cost: one pass over the pixels; at factor 2 a 640x480 frame takes about 1 ms on one core
/// with noisy depth (0.3 ms when the depths barely vary).
/// Thread-safety: touches only `frame`.
/// @throws std::invalid_argument when factor is not in 1..kMaxDecimation.
void DecimateFrame(int factor, core::RgbdFrame* frame);

/// The segmenter parameters for frames decimated by `factor`: those counted in points are
/// divided by factor^2 (objects.min_object_points and partition.min_pixels, at least 1), so
/// the same objects are kept as at full resolution; everything else is in metres, pixels of
/// the grid or shares and stays. Factor 1 returns `params` unchanged.
SegmenterParams ForDecimatedFrames(SegmenterParams params, int factor);

}  // namespace clutterseg::pipeline
