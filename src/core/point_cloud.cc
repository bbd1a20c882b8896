#include "clutterseg/core/point_cloud.h"

#include <atomic>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/simd_points.h"
#include "clutterseg/core/thread_pool.h"

namespace clutterseg::core {

size_t PointCloud::CountValid() const {
  size_t n = 0;
  for (const Vec3f& p : xyz) n += IsValid(p) ? 1 : 0;
  return n;
}

CameraIntrinsics IntrinsicsForCloud(const CameraIntrinsics& intrinsics,
                                    const PointCloudView& cloud) {
  if (cloud.organized() && (intrinsics.width != cloud.width || intrinsics.height != cloud.height)) {
    return intrinsics.Scaled(cloud.width, cloud.height);
  }
  return intrinsics;
}

void CameraIntrinsics::ValidateOrThrow(std::string_view section) const {
  const ParamCheck check(section);
  check.InRange("width", width, 1, 16384, "px");
  check.InRange("height", height, 1, 16384, "px");
  // A real camera sees between about 10 and 150 degrees: fx = width / (2 tan(fov / 2)). A
  // focal length outside that range (a corrupted FOV, a unit mistake) would make every
  // pixel its own voxel or every frame one voxel.
  constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
  const double tan_lo = std::tan(5.0 * kDegToRad), tan_hi = std::tan(75.0 * kDegToRad);
  check.InRange("fx", fx, 0.5 * width / tan_hi, 0.5 * width / tan_lo,
                "px (a horizontal field of view of 10..150 deg)");
  check.InRange("fy", fy, 0.5 * height / tan_hi,
                std::max(0.5 * height / tan_lo, 0.5 * width / tan_lo),
                "px (a vertical field of view of 10..150 deg)");
  check.InRange("cx", cx, -0.5 * width, 1.5 * width, "px (near the image)");
  check.InRange("cy", cy, -0.5 * height, 1.5 * height, "px (near the image)");
}

CameraIntrinsics CameraIntrinsics::Scaled(int new_width, int new_height) const {
  CameraIntrinsics k = *this;
  const double sx = static_cast<double>(new_width) / width;
  const double sy = static_cast<double>(new_height) / height;
  k.width = new_width;
  k.height = new_height;
  k.fx = fx * sx;
  k.fy = fy * sy;
  k.cx = (cx + 0.5) * sx - 0.5;
  k.cy = (cy + 0.5) * sy - 0.5;
  return k;
}

std::string CameraIntrinsics::ToString() const {
  std::ostringstream os;
  os << width << "x" << height << " fx=" << fx << " fy=" << fy << " cx=" << cx << " cy=" << cy;
  return os.str();
}

size_t DepthToPointCloud(const DepthImage& depth, const CameraIntrinsics& k,
                         const ColorImage* color, PointCloud* cloud, float min_m, float max_m,
                         ThreadPool* pool) {
  const int w = depth.width;
  const int h = depth.height;
  cloud->width = w;
  cloud->height = h;
  cloud->xyz.resize(depth.size());
  cloud->label.clear();
  const bool with_color = color != nullptr && color->width == w && color->height == h;
  if (with_color) {
    cloud->rgba.resize(depth.size());
  } else {
    cloud->rgba.clear();
  }
  const float ifx = static_cast<float>(1.0 / k.fx);
  const float ify = static_cast<float>(1.0 / k.fy);
  const float cx = static_cast<float>(k.cx);
  const float cy = static_cast<float>(k.cy);
  const Vec3f invalid{kInvalidDepth, kInvalidDepth, kInvalidDepth};
  constexpr float kInf = std::numeric_limits<float>::infinity();
  // Branch-free per pixel: valid and invalid depths interleave along object edges.
  const size_t num_rows = h > 0 ? static_cast<size_t>(h) : 0;
  constexpr size_t kRowGrain = 32;
  std::atomic<size_t> num_valid{0};  // one addition per chunk of rows
  auto rows = [&](size_t v_begin, size_t v_end) {
    uint32_t valid = 0;
    for (size_t v = v_begin; v < v_end; ++v) {
      const size_t row = v * static_cast<size_t>(w);
      const float yf = (static_cast<float>(v) - cy) * ify;
      const uint16_t* d = depth.data.data() + row;
      Vec3f* out = cloud->xyz.data() + row;
      int u = 0;
#if defined(__SSE2__)
      // Four pixels at a time: the same operations in the same order as the scalar loop below.
      const __m128 vcx = _mm_set1_ps(cx), vifx = _mm_set1_ps(ifx), vyf = _mm_set1_ps(yf);
      const __m128 scale = _mm_set1_ps(0.001f), lo = _mm_set1_ps(min_m), hi = _mm_set1_ps(max_m);
      const __m128 inf = _mm_set1_ps(kInf), nan = _mm_set1_ps(kInvalidDepth);
      const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
      __m128 uf = _mm_setr_ps(0.f, 1.f, 2.f, 3.f);
      for (; u + 4 <= w; u += 4, uf = _mm_add_ps(uf, _mm_set1_ps(4.f))) {
        const __m128i raw = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(d + u));
        const __m128 df = _mm_cvtepi32_ps(_mm_unpacklo_epi16(raw, _mm_setzero_si128()));
        const __m128 z = _mm_mul_ps(df, scale);
        const __m128 x = _mm_mul_ps(_mm_mul_ps(_mm_sub_ps(uf, vcx), vifx), z);
        const __m128 y = _mm_mul_ps(vyf, z);
        const __m128 ok =
            _mm_and_ps(_mm_and_ps(_mm_cmpneq_ps(df, _mm_setzero_ps()),
                                  _mm_and_ps(_mm_cmpge_ps(z, lo), _mm_cmple_ps(z, hi))),
                       _mm_and_ps(_mm_cmplt_ps(_mm_and_ps(x, abs_mask), inf),
                                  _mm_cmplt_ps(_mm_and_ps(y, abs_mask), inf)));
        StoreFourPointsWhere(ok, MakeFourPoints(x, y, z), nan, out + u);
        valid += CountLanes(ok);
      }
#endif
      for (; u < w; ++u) {
        const float z = d[u] * 0.001f;
        const Vec3f p{(static_cast<float>(u) - cx) * ifx * z, yf * z, z};
        // Degenerate intrinsics (a zero focal length from a broken recording) give non-finite
        // x or y: such points are invalid, as the segmenter's depth-range mask makes them.
        const float ax = std::fabs(p.x), ay = std::fabs(p.y);
        const bool ok = (d[u] != 0) & (z >= min_m) & (z <= max_m) & (ax < kInf) & (ay < kInf);
        out[u] = ok ? p : invalid;
        valid += ok ? 1u : 0u;
      }
      if (with_color) {
        for (int i = 0; i < w; ++i) cloud->rgba[row + i] = PackRgba(color->data[row + i]);
      }
    }
    num_valid.fetch_add(valid, std::memory_order_relaxed);
  };
  ForChunks(pool, num_rows, kRowGrain, rows);
  return num_valid.load(std::memory_order_relaxed);
}

}  // namespace clutterseg::core
