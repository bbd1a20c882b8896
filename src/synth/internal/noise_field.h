#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/thread_pool.h"

namespace clutterseg::synth::internal {

/// Fills `out` (resized to width * height, row-major) with a stationary Gaussian random field:
/// zero mean, unit variance at every pixel, and correlation about exp(-(d / correlation_px)^2)
/// between pixels d apart, so correlation_px is the distance at which it falls to 1/e. The
/// field is white noise on a grid of spacing max(1, floor(correlation_px / 3)) px,
/// smoothed by a separable Gaussian kernel on that grid and bilinearly interpolated, with the
/// interpolation's variance loss divided out exactly. correlation_px <= 0 gives independent
/// per-pixel normals. Every grid value comes from a counter-based hash of (seed, cell), so the
/// output depends only on the arguments, never on `pool` or its thread count.
/// Thread-safety: reentrant; `out` must not be shared between concurrent calls.
/// Complexity: O(width * height) for any correlation length.
void CorrelatedGaussianField(uint64_t seed, int width, int height, double correlation_px,
                             std::vector<float>* out, core::ThreadPool* pool = nullptr);

}  // namespace clutterseg::synth::internal
