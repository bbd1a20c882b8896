#include "clutterseg/pipeline/temporal_filter.h"

#include <algorithm>
#include <cmath>

#include "clutterseg/core/param_check.h"

namespace clutterseg::pipeline {

void TemporalFilterParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("max_frames", max_frames, 1, 255, "frames");
  check.InRange("band_at_1m_m", band_at_1m_m, 0.f, 1.f, "m");
  check.InRange("min_band_m", min_band_m, 0.f, 1.f, "m");
  check.InRange("hole_fill_frames", hole_fill_frames, 0, 255, "frames");
}

TemporalDepthFilter::TemporalDepthFilter(const TemporalFilterParams& params)
    : params_((params.ValidateOrThrow(), params)) {}

void TemporalDepthFilter::Reset() {
  std::fill(count_.begin(), count_.end(), uint8_t{0});
  std::fill(missing_.begin(), missing_.end(), uint8_t{0});
  std::fill(mean_mm_.begin(), mean_mm_.end(), 0.f);
}

size_t TemporalDepthFilter::memory_bytes() const {
  return mean_mm_.size() * sizeof(float) + count_.size() + missing_.size();
}

void TemporalDepthFilter::Apply(core::DepthImage* depth) {
  const size_t n = depth->size();
  if (depth->width != width_ || depth->height != height_ || mean_mm_.size() != n) {
    width_ = depth->width;
    height_ = depth->height;
    mean_mm_.assign(n, 0.f);
    count_.assign(n, 0);
    missing_.assign(n, 0);
  }
  // band(z) = max(min_band, band_at_1m z^2) with z in metres, here in millimetres:
  // band_at_1m_m * 1e3 * (d / 1e3)^2 = band_at_1m_m * 1e-3 * d^2.
  const float band_quad = params_.band_at_1m_m * 1e-3f;
  const float band_min = params_.min_band_m * 1e3f;
  const float max_frames = static_cast<float>(params_.max_frames);
  const int hole_fill = params_.hole_fill_frames;
  uint16_t* d = depth->data.data();
  float* mean = mean_mm_.data();
  uint8_t* count = count_.data();
  uint8_t* missing = missing_.data();
  size_t resets = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint16_t raw = d[i];
    if (raw == 0) {
      // A hole: the mean is kept for a measurement within the band after it; the mean is shown
      // only for the first hole_fill_frames frames of the hole.
      if (count[i] != 0 && missing[i] < hole_fill) {
        d[i] = static_cast<uint16_t>(mean[i] + 0.5f);
      }
      if (missing[i] < 255) ++missing[i];
      continue;
    }
    missing[i] = 0;
    const float z = static_cast<float>(raw);
    const float band = std::max(band_min, band_quad * z * z);
    const float m = mean[i];
    if (count[i] == 0 || std::fabs(z - m) > band) {
      mean[i] = z;  // a change (or the first measurement): the new depth as it is
      count[i] = 1;
      ++resets;
      continue;
    }
    const float k = std::min(static_cast<float>(count[i]) + 1.f, max_frames);
    const float next = m + (z - m) / k;
    mean[i] = next;
    count[i] = static_cast<uint8_t>(k);
    d[i] = static_cast<uint16_t>(next + 0.5f);
  }
  num_reset_ = resets;
}

}  // namespace clutterseg::pipeline
