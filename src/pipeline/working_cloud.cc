#include "clutterseg/pipeline/working_cloud.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/scoped_timer.h"
#include "clutterseg/core/simd_points.h"

namespace clutterseg::pipeline {
namespace {

constexpr size_t kPointGrain = 32768;

// Copies points [0, n) from `src` to `dst`, a point outside the depth range [zmin, zmax] or
// with a non-finite coordinate becoming invalid (NaN); returns the number kept. Branch-free
// (valid and invalid points interleave along object edges): a coordinate is finite exactly
// when its magnitude is below infinity.
uint32_t RestrictToDepthRange(const core::Vec3f* src, core::Vec3f* dst, size_t n, float zmin,
                              float zmax) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const core::Vec3f invalid{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth};
  uint32_t valid = 0;
  size_t i = 0;
#if defined(__SSE2__)
  // Four points at a time.
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 inf = _mm_set1_ps(kInf), lo = _mm_set1_ps(zmin), hi = _mm_set1_ps(zmax);
  const __m128 nan = _mm_set1_ps(core::kInvalidDepth);
  for (; i + 4 <= n; i += 4) {
    const core::FourPoints p = core::LoadFourPoints(src + i);
    const __m128 finite = _mm_and_ps(_mm_and_ps(_mm_cmplt_ps(_mm_and_ps(p.x, abs_mask), inf),
                                                _mm_cmplt_ps(_mm_and_ps(p.y, abs_mask), inf)),
                                     _mm_cmplt_ps(_mm_and_ps(p.z, abs_mask), inf));
    const __m128 keep =
        _mm_and_ps(finite, _mm_and_ps(_mm_cmpge_ps(p.z, lo), _mm_cmple_ps(p.z, hi)));
    valid += core::CountLanes(keep);
    core::StoreFourPointsWhere(keep, p, nan, dst + i);
  }
#endif
  for (; i < n; ++i) {
    const core::Vec3f p = src[i];
    const float ax = std::fabs(p.x), ay = std::fabs(p.y), az = std::fabs(p.z);
    const bool ok = (ax < kInf) & (ay < kInf) & (az < kInf) & (p.z >= zmin) & (p.z <= zmax);
    dst[i] = ok ? p : invalid;
    valid += ok ? 1u : 0u;
  }
  return valid;
}

}  // namespace

void PointsParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("min_depth_m", min_depth_m, 0.f, 100.f, "m");
  check.Require(std::isfinite(max_depth_m) && max_depth_m > min_depth_m && max_depth_m <= 100.f,
                "max_depth_m", max_depth_m, "> min_depth_m and <= 100 m");
}

WorkingCloudBuilder::WorkingCloudBuilder(const PointsParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

void WorkingCloudBuilder::Compute(const core::PointCloudView& input, bool keep_color,
                                  WorkingCloud* out) {
  const core::ScopedTimer timer(&out->time_ms);
  core::PointCloud& work = out->cloud;
  work.width = input.width;
  work.height = std::max(input.height, 1);
  work.xyz.resize(input.xyz.size());
  work.label.clear();
  const float zmin = params_.min_depth_m;
  const float zmax = params_.max_depth_m;
  const core::Vec3f* src = input.xyz.data();
  core::Vec3f* dst = work.xyz.data();
  const size_t n = input.xyz.size();
  chunk_valid_.assign(core::ThreadPool::NumChunks(n, kPointGrain), 0);
  core::ForChunks(pool_, n, kPointGrain, [&](size_t b, size_t e) {
    chunk_valid_[b / kPointGrain] = RestrictToDepthRange(src + b, dst + b, e - b, zmin, zmax);
  });
  out->num_valid =
      static_cast<uint32_t>(std::accumulate(chunk_valid_.begin(), chunk_valid_.end(), 0u));
  if (keep_color && input.has_color()) {
    work.rgba.assign(input.rgba.begin(), input.rgba.end());
  } else {
    work.rgba.clear();
  }
}

void WorkingCloudBuilder::Compute(const core::DepthImage& depth, const core::ColorImage* color,
                                  const core::CameraIntrinsics& intrinsics, WorkingCloud* out) {
  const core::ScopedTimer timer(&out->time_ms);
  out->cloud.label.clear();
  out->num_valid = static_cast<uint32_t>(core::DepthToPointCloud(
      depth, intrinsics, color, &out->cloud, params_.min_depth_m, params_.max_depth_m, pool_));
}

}  // namespace clutterseg::pipeline
