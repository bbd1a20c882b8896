#include "clutterseg/pipeline/temporal_filter.h"

#include <algorithm>
#include <cmath>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/simd_points.h"

namespace clutterseg::pipeline {

namespace {

// The filter's constants for one frame, in millimetres.
struct Constants {
  float band_quad;  // band = max(band_min, band_quad d^2)
  float band_min;
  float max_frames;
  uint8_t hole_fill;
};

// One pixel: filters d in place, updates its state; returns whether it was reset.
inline bool FilterPixel(const Constants& k, uint16_t* d, float* mean, uint8_t* count,
                        uint8_t* missing) {
  const uint16_t raw = *d;
  const float z = static_cast<float>(raw);
  const float m = *mean;
  const uint8_t c = *count;
  const uint8_t gone = *missing;
  const bool valid = raw != 0;
  const float band = std::max(k.band_min, k.band_quad * z * z);
  // A change (or the first measurement): the new depth as it is. Otherwise averaged in.
  const bool reset = valid && (c == 0 || std::fabs(z - m) > band);
  const float frames = std::min(static_cast<float>(c) + 1.f, k.max_frames);
  const float next = reset ? z : m + (z - m) / frames;
  // A hole keeps the mean for a measurement within the band after it, and shows the mean
  // for the first hole_fill frames of the hole only.
  const bool fill = !valid && c != 0 && gone < k.hole_fill;
  const float shown = valid ? next : (fill ? m : 0.f);
  *d = static_cast<uint16_t>(shown + 0.5f);
  *mean = valid ? next : m;
  *count = valid ? static_cast<uint8_t>(reset ? 1.f : frames) : c;
  *missing = valid ? uint8_t{0} : static_cast<uint8_t>(std::min(gone + 1, 255));
  return reset;
}

#if defined(__SSE2__)
// Four pixels whose depths, counts and missing counts are given as floats; the same
// arithmetic as FilterPixel, so the same bits. Returns the reset mask.
inline __m128 FilterFour(const Constants& k, __m128 z, float* mean, __m128 c, __m128 gone,
                         __m128* shown, __m128* count_out, __m128* missing_out) {
  const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.f);
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 m = _mm_loadu_ps(mean);
  const __m128 valid = _mm_cmpneq_ps(z, zero);
  const __m128 band =
      _mm_max_ps(_mm_set1_ps(k.band_min), _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(k.band_quad), z), z));
  const __m128 diff = _mm_sub_ps(z, m);
  const __m128 reset = _mm_and_ps(
      valid, _mm_or_ps(_mm_cmpeq_ps(c, zero), _mm_cmpgt_ps(_mm_and_ps(diff, abs_mask), band)));
  const __m128 frames = _mm_min_ps(_mm_add_ps(c, one), _mm_set1_ps(k.max_frames));
  const __m128 averaged = _mm_add_ps(m, _mm_div_ps(diff, frames));
  const __m128 next = _mm_or_ps(_mm_and_ps(reset, z), _mm_andnot_ps(reset, averaged));
  const __m128 fill = _mm_andnot_ps(
      valid, _mm_and_ps(_mm_cmpneq_ps(c, zero), _mm_cmplt_ps(gone, _mm_set1_ps(k.hole_fill))));
  *shown = _mm_or_ps(_mm_and_ps(valid, next), _mm_and_ps(fill, m));
  _mm_storeu_ps(mean, _mm_or_ps(_mm_and_ps(valid, next), _mm_andnot_ps(valid, m)));
  const __m128 counted = _mm_or_ps(_mm_and_ps(reset, one), _mm_andnot_ps(reset, frames));
  *count_out = _mm_or_ps(_mm_and_ps(valid, counted), _mm_andnot_ps(valid, c));
  *missing_out = _mm_andnot_ps(valid, _mm_min_ps(_mm_add_ps(gone, one), _mm_set1_ps(255.f)));
  return reset;
}

// Eight uint8 (the low 8 bytes of v) as two vectors of four floats.
inline void BytesToFloats(__m128i v, __m128* lo, __m128* hi) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i w = _mm_unpacklo_epi8(v, zero);
  *lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, zero));
  *hi = _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, zero));
}

// Two vectors of four floats in 0..255 (whole numbers) as eight uint8 in the low 8 bytes.
inline __m128i FloatsToBytes(__m128 lo, __m128 hi) {
  const __m128i w = _mm_packs_epi32(_mm_cvttps_epi32(lo), _mm_cvttps_epi32(hi));
  return _mm_packus_epi16(w, w);
}

// Two vectors of four floats in 0..65535 (truncated) as eight uint16 (SSE2 has no unsigned
// 32 -> 16 pack: shift into the signed range, pack with saturation, shift back).
inline __m128i FloatsToU16(__m128 lo, __m128 hi) {
  const __m128i bias = _mm_set1_epi32(32768);
  const __m128i a = _mm_sub_epi32(_mm_cvttps_epi32(lo), bias);
  const __m128i b = _mm_sub_epi32(_mm_cvttps_epi32(hi), bias);
  return _mm_add_epi16(_mm_packs_epi32(a, b), _mm_set1_epi16(static_cast<short>(-32768)));
}
#endif

}  // namespace

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
  const Constants k{params_.band_at_1m_m * 1e-3f, params_.min_band_m * 1e3f,
                    static_cast<float>(params_.max_frames),
                    static_cast<uint8_t>(params_.hole_fill_frames)};
  uint16_t* d = depth->data.data();
  float* mean = mean_mm_.data();
  uint8_t* count = count_.data();
  uint8_t* missing = missing_.data();
  size_t resets = 0;
  size_t i = 0;
#if defined(__SSE2__)
  // Eight pixels at a time, branch-free (changes and holes are scattered along every edge).
  const __m128i zero = _mm_setzero_si128();
  for (; i + 8 <= n; i += 8) {
    const __m128i raw = _mm_loadu_si128(reinterpret_cast<const __m128i*>(d + i));
    const __m128 z_lo = _mm_cvtepi32_ps(_mm_unpacklo_epi16(raw, zero));
    const __m128 z_hi = _mm_cvtepi32_ps(_mm_unpackhi_epi16(raw, zero));
    __m128 c_lo, c_hi, g_lo, g_hi;
    BytesToFloats(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(count + i)), &c_lo, &c_hi);
    BytesToFloats(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(missing + i)), &g_lo, &g_hi);
    __m128 shown_lo, shown_hi, cnt_lo, cnt_hi, miss_lo, miss_hi;
    const __m128 r_lo = FilterFour(k, z_lo, mean + i, c_lo, g_lo, &shown_lo, &cnt_lo, &miss_lo);
    const __m128 r_hi = FilterFour(k, z_hi, mean + i + 4, c_hi, g_hi, &shown_hi, &cnt_hi, &miss_hi);
    const __m128 half = _mm_set1_ps(0.5f);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(d + i),
                     FloatsToU16(_mm_add_ps(shown_lo, half), _mm_add_ps(shown_hi, half)));
    _mm_storel_epi64(reinterpret_cast<__m128i*>(count + i), FloatsToBytes(cnt_lo, cnt_hi));
    _mm_storel_epi64(reinterpret_cast<__m128i*>(missing + i), FloatsToBytes(miss_lo, miss_hi));
    resets += core::CountLanes(r_lo) + core::CountLanes(r_hi);
  }
#endif
  for (; i < n; ++i) {
    resets += FilterPixel(k, d + i, mean + i, count + i, missing + i) ? 1u : 0u;
  }
  num_reset_ = resets;
}

}  // namespace clutterseg::pipeline
