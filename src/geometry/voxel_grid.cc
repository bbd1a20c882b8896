#include "clutterseg/geometry/voxel_grid.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "clutterseg/core/assert.h"
#include "clutterseg/core/param_check.h"
#include "clutterseg/core/simd_points.h"
#include "clutterseg/geometry/moments.h"

namespace clutterseg::geometry {
namespace {

constexpr int kFieldBits = 21;
constexpr int32_t kOffset = 1 << 20;
// Coordinates are kept strictly inside (-kOffset + 1, kOffset - 1) so that the packed keys of
// all 26 neighbours stay valid.
constexpr int32_t kCoordLimit = kOffset - 2;
constexpr uint64_t kFieldMask = (uint64_t{1} << kFieldBits) - 1;
constexpr uint64_t kInvalidKey = ~uint64_t{0};
constexpr size_t kBandPoints = 16384;
constexpr size_t kVoxelGrain = 2048;
constexpr uint64_t kMaxCells = uint64_t{1} << 20;  // cells of the column table, at most
constexpr uint32_t kNoVoxel = ~uint32_t{0};
constexpr size_t kMaxPartitions = 64;      // ranges of x, at most (one per thread)
constexpr uint64_t kMaxWindowBins = 1024;  // bins of the points per x that cut the ranges

// Packed key: x, y, z (offset to be non-negative) in 21-bit fields, x most significant.
inline uint64_t PackKey(int32_t x, int32_t y, int32_t z) {
  return (static_cast<uint64_t>(x + kOffset) << (2 * kFieldBits)) |
         (static_cast<uint64_t>(y + kOffset) << kFieldBits) | static_cast<uint64_t>(z + kOffset);
}

inline VoxelCoord UnpackKey(uint64_t key) {
  return VoxelCoord{static_cast<int32_t>((key >> (2 * kFieldBits)) & kFieldMask) - kOffset,
                    static_cast<int32_t>((key >> kFieldBits) & kFieldMask) - kOffset,
                    static_cast<int32_t>(key & kFieldMask) - kOffset};
}

// Natural logarithm of 4 positive normal floats (other lanes give unspecified values):
// z = m 2^e with m in [sqrt(1/2), sqrt(2)), ln m = 2 atanh(t) with t = (m - 1) / (m + 1),
// |t| <= 0.172, by its series to t^9 (relative error below 1e-7, like logf). Every point,
// quantised alone or in a block of four, goes through this same code, so equal depths always
// get equal keys.
#if defined(__SSE2__)
using Float4 = __m128;
inline Float4 Ln4(Float4 z) {
  const __m128i bits = _mm_castps_si128(z);
  __m128i e = _mm_sub_epi32(_mm_srli_epi32(bits, 23), _mm_set1_epi32(127));
  __m128 m = _mm_castsi128_ps(
      _mm_or_si128(_mm_and_si128(bits, _mm_set1_epi32(0x007fffff)), _mm_set1_epi32(0x3f800000)));
  const __m128 big = _mm_cmpgt_ps(m, _mm_set1_ps(1.41421356f));
  m = _mm_or_ps(_mm_and_ps(big, _mm_mul_ps(m, _mm_set1_ps(0.5f))), _mm_andnot_ps(big, m));
  e = _mm_sub_epi32(e, _mm_castps_si128(big));  // big lanes are -1 as integers
  const __m128 one = _mm_set1_ps(1.f);
  const __m128 t = _mm_div_ps(_mm_sub_ps(m, one), _mm_add_ps(m, one));
  const __m128 t2 = _mm_mul_ps(t, t);
  __m128 poly = _mm_add_ps(_mm_mul_ps(t2, _mm_set1_ps(1.f / 9.f)), _mm_set1_ps(1.f / 7.f));
  poly = _mm_add_ps(_mm_mul_ps(poly, t2), _mm_set1_ps(1.f / 5.f));
  poly = _mm_add_ps(_mm_mul_ps(poly, t2), _mm_set1_ps(1.f / 3.f));
  poly = _mm_add_ps(_mm_mul_ps(poly, t2), one);
  const __m128 ln_m = _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(2.f), t), poly);
  return _mm_add_ps(_mm_mul_ps(_mm_cvtepi32_ps(e), _mm_set1_ps(0.693147181f)), ln_m);
}
#endif

// Packed keys of four points; kInvalidKey for non-finite points, z <= 0 with the camera
// transform, and coordinates outside the key range. Floors are
// exact for |q| < 2^20 (truncation, minus one where that rounded up).
#if defined(__SSE2__)
inline void QuantizeFour(__m128 vx, __m128 vy, __m128 vz, bool camera, float inv_res,
                         uint64_t* keys) {
  constexpr float kLim = static_cast<float>(kCoordLimit);
  const __m128 res = _mm_set1_ps(inv_res);
  __m128 qx, qy, qz, valid;
  if (camera) {
    const __m128 inv_z = _mm_div_ps(_mm_set1_ps(1.f), vz);
    qx = _mm_mul_ps(_mm_mul_ps(vx, inv_z), res);
    qy = _mm_mul_ps(_mm_mul_ps(vy, inv_z), res);
    qz = _mm_mul_ps(Ln4(vz), res);
    valid = _mm_cmpgt_ps(vz, _mm_setzero_ps());
  } else {
    qx = _mm_mul_ps(vx, res);
    qy = _mm_mul_ps(vy, res);
    qz = _mm_mul_ps(vz, res);
    valid = _mm_castsi128_ps(_mm_set1_epi32(-1));
  }
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 lim = _mm_set1_ps(kLim);
  valid = _mm_and_ps(valid, _mm_cmplt_ps(_mm_and_ps(qx, abs_mask), lim));
  valid = _mm_and_ps(valid, _mm_cmplt_ps(_mm_and_ps(qy, abs_mask), lim));
  valid = _mm_and_ps(valid, _mm_cmplt_ps(_mm_and_ps(qz, abs_mask), lim));
  const __m128i offset = _mm_set1_epi32(kOffset);
  auto field = [&](__m128 q) {  // floor(q) + kOffset, non-negative
    const __m128i t = _mm_cvttps_epi32(q);
    return _mm_add_epi32(_mm_add_epi32(t, _mm_castps_si128(_mm_cmpgt_ps(_mm_cvtepi32_ps(t), q))),
                         offset);
  };
  const __m128i fx = field(qx), fy = field(qy), fz = field(qz);
  const __m128i zero = _mm_setzero_si128();
  const __m128i vmask = _mm_castps_si128(valid);
  // Two 64-bit keys per register: (x << 42) | (y << 21) | z, all ones where invalid.
  auto pack = [&](__m128i x2, __m128i y2, __m128i z2, __m128i m2) {
    const __m128i key = _mm_or_si128(
        _mm_or_si128(_mm_slli_epi64(x2, 2 * kFieldBits), _mm_slli_epi64(y2, kFieldBits)), z2);
    return _mm_or_si128(_mm_and_si128(m2, key), _mm_andnot_si128(m2, _mm_set1_epi32(-1)));
  };
  _mm_storeu_si128(reinterpret_cast<__m128i*>(keys),
                   pack(_mm_unpacklo_epi32(fx, zero), _mm_unpacklo_epi32(fy, zero),
                        _mm_unpacklo_epi32(fz, zero), _mm_unpacklo_epi32(vmask, vmask)));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(keys + 2),
                   pack(_mm_unpackhi_epi32(fx, zero), _mm_unpackhi_epi32(fy, zero),
                        _mm_unpackhi_epi32(fz, zero), _mm_unpackhi_epi32(vmask, vmask)));
}
#endif

// Keys of points [0, n) (see QuantizeFour): four at a time, the rest padded with invalid
// points, so that a point's key never depends on its position.
inline void QuantizePoints(const core::Vec3f* p, size_t n, bool camera, float inv_res,
                           uint64_t* keys) {
#if defined(__SSE2__)
  size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const core::FourPoints four = core::LoadFourPoints(p + i);
    // Cropped and out-of-range pixels come in long runs of NaN depths, invalid whatever the
    // transform: their keys without the arithmetic (the branch predicts well on such runs).
    if (_mm_movemask_ps(_mm_cmpord_ps(four.z, four.z)) == 0) {
      std::fill_n(keys + i, 4, kInvalidKey);
      continue;
    }
    QuantizeFour(four.x, four.y, four.z, camera, inv_res, keys + i);
  }
  if (i < n) {
    float x[4] = {0.f, 0.f, 0.f, 0.f}, y[4] = {0.f, 0.f, 0.f, 0.f};
    float z[4] = {-1.f, -1.f, -1.f, -1.f};
    for (size_t k = 0; i + k < n; ++k) {
      x[k] = p[i + k].x;
      y[k] = p[i + k].y;
      z[k] = p[i + k].z;
    }
    uint64_t tail[4];
    QuantizeFour(_mm_loadu_ps(x), _mm_loadu_ps(y), _mm_loadu_ps(z), camera, inv_res, tail);
    std::copy_n(tail, n - i, keys + i);
  }
#else
  constexpr float kLim = static_cast<float>(kCoordLimit);
  for (size_t i = 0; i < n; ++i) {
    const core::Vec3f& q = p[i];
    float qx, qy, qz;
    bool ok;
    if (camera) {
      const float inv_z = 1.f / q.z;
      qx = q.x * inv_z * inv_res;
      qy = q.y * inv_z * inv_res;
      qz = std::log(q.z) * inv_res;
      ok = q.z > 0.f;
    } else {
      qx = q.x * inv_res;
      qy = q.y * inv_res;
      qz = q.z * inv_res;
      ok = true;
    }
    ok = ok && std::fabs(qx) < kLim && std::fabs(qy) < kLim && std::fabs(qz) < kLim;
    keys[i] =
        ok ? PackKey(static_cast<int32_t>(std::floor(qx)), static_cast<int32_t>(std::floor(qy)),
                     static_cast<int32_t>(std::floor(qz)))
           : kInvalidKey;
  }
#endif
}

using core::ForChunks;

}  // namespace

void VoxelGridParams::ValidateOrThrow(std::string_view section) const {
  const core::ParamCheck check(section);
  check.InRange("voxel_resolution_m", voxel_resolution_m, 1e-4f, 1.0f, "m");
}

uint64_t PackVoxelKey(const VoxelCoord& c) { return PackKey(c.x, c.y, c.z); }

int32_t VoxelGrid::FindVoxel(const VoxelCoord& c) const {
  if (std::abs(c.x) > kCoordLimit || std::abs(c.y) > kCoordLimit || std::abs(c.z) > kCoordLimit) {
    return -1;
  }
  const uint64_t k = PackKey(c.x, c.y, c.z);
  const auto it = std::lower_bound(key.begin(), key.end(), k);
  if (it == key.end() || *it != k) return -1;
  return static_cast<int32_t>(it - key.begin());
}

Voxelizer::Voxelizer(const VoxelGridParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

float Voxelizer::VoxelSizeAt(float z_m) const {
  return params_.use_single_camera_transform ? params_.voxel_resolution_m * z_m
                                             : params_.voxel_resolution_m;
}

bool Voxelizer::Quantize(const core::Vec3f& p, VoxelCoord* c) const {
  uint64_t key;
  QuantizePoints(&p, 1, params_.use_single_camera_transform, 1.0f / params_.voxel_resolution_m,
                 &key);
  if (key == kInvalidKey) return false;
  *c = UnpackKey(key);
  return true;
}

void Voxelizer::Voxelize(const core::PointCloud& cloud, bool mean_color, VoxelGrid* grid) {
  core::ThreadPool* const pool = pool_;
  CLUTTERSEG_DEMAND(grid != nullptr);
  const size_t n = cloud.size();
  const bool organized = cloud.organized() &&
                         static_cast<size_t>(cloud.width) * static_cast<size_t>(cloud.height) == n;
  const size_t w = organized ? static_cast<size_t>(cloud.width) : 0;
  const bool with_color = mean_color && cloud.rgba.size() == n && n > 0;
  grid->width = cloud.width;
  grid->height = cloud.height;
  grid->params = params_;
  grid->adjacency_offsets.clear();
  grid->adjacency.clear();
  grid->normal.clear();
  grid->curvature.clear();

  // 1. Keys of all points (invalid points get no voxel here); per band the number of valid
  // keys, the box of their (x, y), and with more than one range of x the band's points per x
  // (over the window of x the previous frame set), with a single range the band's points in
  // point order.
  pixel_key_.resize(n);
  grid->point_voxel.resize(n);
  const bool camera = params_.use_single_camera_transform;
  const float inv_res = 1.0f / params_.voxel_resolution_m;
  const size_t num_bands = core::ThreadPool::NumChunks(n, kBandPoints);
  const size_t num_partitions = std::min(
      kMaxPartitions, static_cast<size_t>(pool != nullptr ? std::max(1, pool->num_threads()) : 1));
  partitions_.resize(num_partitions);
  // Range p takes the x in [cut[p], cut[p + 1]): the first from 0, the last to the end.
  partition_cut_.assign(num_partitions + 1, 0);
  partition_cut_.back() = kFieldMask + 1;
  const bool count_x = num_partitions > 1 && window_bins_ > 0;
  const uint64_t window_min = window_min_, window_bins = window_bins_;
  const int window_shift = window_shift_;
  band_histogram_.resize(count_x ? num_bands * window_bins : 0);
  band_range_.resize(num_bands);
  band_points_.resize(n);
  band_offset_.resize(num_bands * (num_partitions + 1));
  ForChunks(pool, n, kBandPoints, [&](size_t begin, size_t end) {
    const size_t band = begin / kBandPoints;
    uint64_t* keys = pixel_key_.data();
    int32_t* point_voxel = grid->point_voxel.data();
    QuantizePoints(cloud.xyz.data() + begin, end - begin, camera, inv_res, keys + begin);
    BandRange range{0, kFieldMask, 0, kFieldMask, 0};
    uint32_t* const hist = count_x ? &band_histogram_[band * window_bins] : nullptr;
    if (count_x) std::fill_n(hist, window_bins, 0u);
    for (size_t i = begin; i < end; ++i) {
      const uint64_t key = keys[i];
      if (key == kInvalidKey) {
        point_voxel[i] = -1;
        continue;
      }
      const uint64_t x = key >> (2 * kFieldBits), y = (key >> kFieldBits) & kFieldMask;
      ++range.valid;
      range.x_min = std::min(range.x_min, x);
      range.x_max = std::max(range.x_max, x);
      range.y_min = std::min(range.y_min, y);
      range.y_max = std::max(range.y_max, y);
      if (count_x) {  // x outside the window counts in its first or last bin
        const uint64_t bin = x < window_min ? 0 : (x - window_min) >> window_shift;
        ++hist[std::min(bin, window_bins - 1)];
      }
    }
    band_range_[band] = range;
    if (num_partitions == 1) CollectBandPoints(band, begin, end);
  });
  BandRange box{0, kFieldMask, 0, kFieldMask, 0};
  for (const BandRange& range : band_range_) {
    if (range.valid == 0) continue;
    box.valid += range.valid;
    box.x_min = std::min(box.x_min, range.x_min);
    box.x_max = std::max(box.x_max, range.x_max);
    box.y_min = std::min(box.y_min, range.y_min);
    box.y_max = std::max(box.y_max, range.y_max);
  }
  if (num_partitions > 1 && box.valid > 0) {
    // Cut where this frame's points split evenly (even cuts of its range of x on a first
    // frame). Any cuts give the same grid: they only balance the work.
    if (count_x) {
      CutAtCounts(num_bands, box.valid);
    } else {
      for (size_t p = 1; p < num_partitions; ++p) {
        partition_cut_[p] = box.x_min + (box.x_max + 1 - box.x_min) * p / num_partitions;
      }
    }
    ForChunks(pool, n, kBandPoints, [&](size_t begin, size_t end) {
      CollectBandPoints(begin / kBandPoints, begin, end);
    });
  }
  // The next frame counts its points per x over this frame's range of x, a quarter wider on
  // each side, in at most kMaxWindowBins bins.
  if (box.valid > 0) {
    const uint64_t span = box.x_max - box.x_min + 1, margin = span / 4 + 1;
    window_min_ = box.x_min > margin ? box.x_min - margin : 0;
    const uint64_t width = span + 2 * margin;
    window_shift_ = 0;
    while ((width >> window_shift_) >= kMaxWindowBins) ++window_shift_;
    window_bins_ = (width >> window_shift_) + 1;
  }
  if (box.valid == 0) {
    for (Partition& part : partitions_) part.size = 0;
    grid->key.clear();
    grid->coord.clear();
    grid->num_points.clear();
    grid->point_sums.clear();
    grid->centroid.clear();
    grid->mean_color.clear();
    return;
  }
  // The ranges, within this frame's box (clamping needs a non-empty one).
  for (size_t p = 0; p < num_partitions; ++p) {
    Partition& part = partitions_[p];
    part.x_begin = std::clamp(partition_cut_[p], box.x_min, box.x_max + 1);
    part.x_end = std::clamp(partition_cut_[p + 1], part.x_begin, box.x_max + 1);
  }

  // 2. The cell table: one cell per column, x-major; where the box has more columns than
  // kMaxCells, a cell holds 2^y_shift consecutive columns of one x (its chain stays sorted by
  // key, so cells in order are still voxels in key order).
  const uint64_t x0 = box.x_min, y0 = box.y_min;
  const uint64_t nx = box.x_max - x0 + 1, ny = box.y_max - y0 + 1;
  int y_shift = 0;
  while (nx * (((ny - 1) >> y_shift) + 1) > kMaxCells && (ny >> y_shift) > 1) ++y_shift;
  const uint64_t ny_cells = ((ny - 1) >> y_shift) + 1;
  cell_head_.assign(nx * ny_cells, kNoVoxel);
  auto cell_of = [&](uint64_t key) {
    return ((key >> (2 * kFieldBits)) - x0) * ny_cells +
           ((((key >> kFieldBits) & kFieldMask) - y0) >> y_shift);
  };

  // 3. Each range of x: its voxels in first-occurrence order, linked into their cells in key
  // order; the cells in order then rank them by key. point_voxel holds the range's voxel for
  // now.
  ForChunks(pool, num_partitions, 1, [&](size_t pb, size_t pe) {
    for (size_t p = pb; p < pe; ++p) {
      Partition& part = partitions_[p];
      uint32_t count = 0;
      const uint64_t* keys = pixel_key_.data();
      int32_t* point_voxel = grid->point_voxel.data();
      uint32_t* head = cell_head_.data();
      for (size_t b = 0; b < num_bands; ++b) {
        const size_t* const offset = &band_offset_[b * (num_partitions + 1)];
        for (size_t j = offset[p]; j < offset[p + 1]; ++j) {
          const size_t i = band_points_[j];
          const uint64_t key = keys[i];
          // Equal keys lie in the same range, so the previous and upper pixels' voxels are
          // this range's when their keys match (the previous pixel may end the row above: an
          // equal key is the same voxel wherever it is).
          if (i > 0 && keys[i - 1] == key) {
            point_voxel[i] = point_voxel[i - 1];
            continue;
          }
          if (organized && i >= w && keys[i - w] == key) {
            point_voxel[i] = point_voxel[i - w];
            continue;
          }
          uint32_t* link = &head[cell_of(key)];
          while (*link != kNoVoxel && part.key[*link] < key) link = &part.next[*link];
          if (*link == kNoVoxel || part.key[*link] != key) {
            if (count == part.key.size()) {
              const size_t capacity = std::max<size_t>(1024, 2 * size_t{count});
              part.key.resize(capacity);
              part.next.resize(capacity);
              // `link` may point into `next`, which moved: find it again.
              link = &head[cell_of(key)];
              while (*link != kNoVoxel && part.key[*link] < key) link = &part.next[*link];
            }
            part.key[count] = key;
            part.next[count] = *link;
            *link = count++;
          }
          point_voxel[i] = static_cast<int32_t>(*link);
        }
      }
      part.size = count;
      part.rank.resize(count);
      uint32_t r = 0;
      const uint64_t cell_begin = (part.x_begin - x0) * ny_cells;
      const uint64_t cell_end = (part.x_end - x0) * ny_cells;
      for (uint64_t c = cell_begin; c < cell_end && r < count; ++c) {
        for (uint32_t v = head[c]; v != kNoVoxel; v = part.next[v]) {
          part.rank[v] = r++;
        }
      }
      CLUTTERSEG_DEMAND(r == count);
    }
  });
  size_t num_voxels = 0;
  for (Partition& part : partitions_) {
    part.first_voxel = num_voxels;
    num_voxels += part.size;
  }

  // 4. Each range again: its voxels' keys in order, then the points' grid voxels and the
  // voxels' sums (added in point order), then centroids and mean colours.
  grid->key.resize(num_voxels);
  grid->coord.resize(num_voxels);
  grid->num_points.resize(num_voxels);
  grid->point_sums.resize(9 * num_voxels);
  grid->centroid.resize(num_voxels);
  grid->mean_color.resize(with_color ? num_voxels : 0);
  ForChunks(pool, num_partitions, 1, [&](size_t pb, size_t pe) {
    for (size_t p = pb; p < pe; ++p) {
      const Partition& part = partitions_[p];
      const size_t first = part.first_voxel, last = first + part.size;
      for (size_t l = 0; l < part.size; ++l) {
        const uint64_t key = part.key[l];
        grid->key[first + part.rank[l]] = key;
        grid->coord[first + part.rank[l]] = UnpackKey(key);
      }
      std::fill(grid->num_points.begin() + first, grid->num_points.begin() + last, 0u);
      std::fill(grid->point_sums.begin() + 9 * first, grid->point_sums.begin() + 9 * last, 0.0);
      if (with_color) {
        std::fill(grid->mean_color.begin() + first, grid->mean_color.begin() + last, core::Vec3f{});
      }
      const core::Vec3f* xyz = cloud.xyz.data();
      int32_t* point_voxel = grid->point_voxel.data();
      for (size_t b = 0; b < num_bands; ++b) {
        const size_t* const offset = &band_offset_[b * (num_partitions + 1)];
        for (size_t j = offset[p]; j < offset[p + 1]; ++j) {
          const size_t i = band_points_[j];
          const uint32_t v =
              static_cast<uint32_t>(first) + part.rank[static_cast<size_t>(point_voxel[i])];
          point_voxel[i] = static_cast<int32_t>(v);
          AddToSums(xyz[i], &grid->point_sums[9 * size_t{v}]);
          ++grid->num_points[v];
          if (with_color) {
            const core::Rgb8 rgb = core::UnpackRgba(cloud.rgba[i]);
            core::Vec3f& m = grid->mean_color[v];
            m.x += rgb.r;
            m.y += rgb.g;
            m.z += rgb.b;
          }
        }
      }
      for (size_t v = first; v < last; ++v) {
        const double* src = &grid->point_sums[9 * v];
        const double inv = 1.0 / grid->num_points[v];
        grid->centroid[v] =
            core::Vec3f{static_cast<float>(src[0] * inv), static_cast<float>(src[1] * inv),
                        static_cast<float>(src[2] * inv)};
        if (with_color) {
          const float finv = static_cast<float>(inv);
          core::Vec3f& m = grid->mean_color[v];
          m = core::Vec3f{m.x * finv, m.y * finv, m.z * finv};
        }
      }
    }
  });
}

void Voxelizer::CutAtCounts(size_t num_bands, size_t total) {
  const size_t num_partitions = partitions_.size();
  const uint64_t bins = window_bins_;
  size_t p = 1, running = 0;
  for (uint64_t b = 0; b < bins && p < num_partitions; ++b) {
    for (size_t band = 0; band < num_bands; ++band) running += band_histogram_[band * bins + b];
    while (p < num_partitions && running * num_partitions >= total * p) {
      partition_cut_[p++] = window_min_ + ((b + 1) << window_shift_);
    }
  }
}

void Voxelizer::CollectBandPoints(size_t band, size_t begin, size_t end) {
  const size_t num_partitions = partitions_.size();
  auto partition_of = [&](uint64_t key) {
    const uint64_t x = key >> (2 * kFieldBits);
    size_t p = 0;
    while (p + 1 < num_partitions && x >= partition_cut_[p + 1]) ++p;
    return p;
  };
  // Counted first, then written: the band's slice of band_points_ holds its valid points
  // range by range, each in point order.
  size_t* const offset = &band_offset_[band * (num_partitions + 1)];
  const uint64_t* const keys = pixel_key_.data();
  uint32_t* const out = band_points_.data();
  if (num_partitions == 1) {
    // One range (one thread): the band's valid points in point order, written without a
    // branch (valid and invalid keys interleave along object edges); band_points_ has a slot
    // for every point, so the store past the last valid one stays inside the band.
    size_t next = begin;
    for (size_t i = begin; i < end; ++i) {
      out[next] = static_cast<uint32_t>(i);
      next += keys[i] != kInvalidKey ? 1 : 0;
    }
    offset[0] = begin;
    offset[1] = next;
    return;
  }
  std::fill(offset, offset + num_partitions + 1, 0);
  for (size_t i = begin; i < end; ++i) {
    if (pixel_key_[i] != kInvalidKey) ++offset[partition_of(pixel_key_[i]) + 1];
  }
  offset[0] = begin;
  for (size_t p = 0; p < num_partitions; ++p) offset[p + 1] += offset[p];
  size_t next[kMaxPartitions];
  std::copy(offset, offset + num_partitions, next);
  for (size_t i = begin; i < end; ++i) {
    if (pixel_key_[i] != kInvalidKey) {
      band_points_[next[partition_of(pixel_key_[i])]++] = static_cast<uint32_t>(i);
    }
  }
}

void Voxelizer::ComputeAdjacency(VoxelGrid* grid) {
  core::ThreadPool* const pool = pool_;
  CLUTTERSEG_DEMAND(grid != nullptr);
  const size_t num_voxels = grid->size();
  grid->adjacency_offsets.assign(num_voxels + 1, 0);
  grid->adjacency.clear();
  if (num_voxels == 0) return;

  // Columns: runs of voxels sharing (x, y), in ascending (x, y) order, each sorted by z.
  column_key_.clear();
  column_begin_.clear();
  for (size_t v = 0; v < num_voxels; ++v) {
    const uint64_t ck = grid->key[v] >> kFieldBits;
    if (column_key_.empty() || column_key_.back() != ck) {
      column_key_.push_back(ck);
      column_begin_.push_back(static_cast<uint32_t>(v));
    }
  }
  const size_t num_columns = column_key_.size();
  column_begin_.push_back(static_cast<uint32_t>(num_voxels));
  nbr_count_.resize(num_voxels);

  // For every column, its 8 neighbour columns are found by pointers that only move forward
  // (one per row x-1, x, x+1); within a pair of columns a second pointer walks z. Neighbours
  // come out in ascending index order because index order is (x, y, z) order.
  // Each chunk of columns writes its voxels' neighbours densely into a list of its own, which
  // is copied into place once all counts are known.
  constexpr size_t kColumnGrain = 1024;
  constexpr uint32_t kMaxFlatCandidates = 48;
  const size_t num_chunks = core::ThreadPool::NumChunks(num_columns, kColumnGrain);
  if (chunk_nbr_.size() < num_chunks) chunk_nbr_.resize(num_chunks);
  ForChunks(pool, num_columns, kColumnGrain, [&](size_t cb, size_t ce) {
    std::vector<uint32_t>& list = chunk_nbr_[cb / kColumnGrain];
    size_t list_size = 0;
    const uint64_t* ckeys = column_key_.data();
    const uint64_t one_x = uint64_t{1} << kFieldBits;
    size_t row_ptr[3];
    {
      const uint64_t first = ckeys[cb];
      for (int r = 0; r < 3; ++r) {
        const uint64_t target = first + (r - 1) * one_x - 1;  // (x + r - 1, y - 1)
        row_ptr[r] =
            static_cast<size_t>(std::lower_bound(ckeys, ckeys + num_columns, target) - ckeys);
      }
    }
    for (size_t c = cb; c < ce; ++c) {
      const uint64_t ck = ckeys[c];
      // Neighbour column ranges in (x, y) order; slot 4 is the column itself.
      uint32_t nb_begin[9], nb_end[9], lo[9];
      for (int r = 0; r < 3; ++r) {
        const uint64_t target = ck + (r - 1) * one_x - 1;
        size_t p = row_ptr[r];
        while (p < num_columns && ckeys[p] < target) ++p;
        row_ptr[r] = p;
        for (int dy = 0; dy < 3; ++dy) {
          const int slot = 3 * r + dy;
          while (p < num_columns && ckeys[p] < target + dy) ++p;
          if (p < num_columns && ckeys[p] == target + dy) {
            nb_begin[slot] = column_begin_[p];
            nb_end[slot] = column_begin_[p + 1];
          } else {
            nb_begin[slot] = nb_end[slot] = 0;
          }
          lo[slot] = nb_begin[slot];
        }
      }
      const uint32_t self_begin = column_begin_[c];
      const uint32_t self_end = column_begin_[c + 1];
      nb_begin[4] = self_begin;
      nb_end[4] = self_end;
      uint32_t num_candidates = 0;
      for (int slot = 0; slot < 9; ++slot) num_candidates += nb_end[slot] - nb_begin[slot];
      if (num_candidates <= kMaxFlatCandidates) {
        // Short columns (the common case): the voxels of all nine columns, in index order, are
        // tested against each voxel of this one without a branch (the walk below branches on
        // every step).
        uint32_t cand[kMaxFlatCandidates];
        int32_t cand_z[kMaxFlatCandidates];
        uint32_t n = 0;
        for (int slot = 0; slot < 9; ++slot) {
          for (uint32_t q = nb_begin[slot]; q < nb_end[slot]; ++q) {
            cand[n] = q;
            cand_z[n] = grid->coord[q].z;
            ++n;
          }
        }
        for (uint32_t a = self_begin; a < self_end; ++a) {
          const int32_t za = grid->coord[a].z;
          if (list.size() < list_size + n) list.resize(std::max(2 * list.size(), list_size + n));
          uint32_t* out = list.data() + list_size;
          uint32_t count = 0;
          for (uint32_t k = 0; k < n; ++k) {
            out[count] = cand[k];
            // z within one of za (distinct within a column, so at most 26 in all), a excluded.
            count += static_cast<uint32_t>((static_cast<uint32_t>(cand_z[k] - za + 1) <= 2u) &
                                           (cand[k] != a));
          }
          nbr_count_[a] = static_cast<uint8_t>(count);
          list_size += count;
        }
        continue;
      }
      for (uint32_t a = self_begin; a < self_end; ++a) {
        const int32_t za = grid->coord[a].z;
        if (list.size() < list_size + 26) list.resize(std::max(2 * list.size(), list_size + 26));
        uint32_t* out = list.data() + list_size;
        int count = 0;
        for (int slot = 0; slot < 9; ++slot) {
          if (slot == 4) {
            if (a > self_begin && grid->coord[a - 1].z == za - 1) out[count++] = a - 1;
            if (a + 1 < self_end && grid->coord[a + 1].z == za + 1) out[count++] = a + 1;
            continue;
          }
          uint32_t q = lo[slot];
          const uint32_t end = nb_end[slot];
          while (q < end && grid->coord[q].z < za - 1) ++q;
          lo[slot] = q;
          for (; q < end && grid->coord[q].z <= za + 1; ++q) out[count++] = q;
        }
        nbr_count_[a] = static_cast<uint8_t>(count);
        list_size += static_cast<size_t>(count);
      }
    }
  });
  for (size_t v = 0; v < num_voxels; ++v) {
    grid->adjacency_offsets[v + 1] = grid->adjacency_offsets[v] + nbr_count_[v];
  }
  grid->adjacency.resize(grid->adjacency_offsets[num_voxels]);
  ForChunks(pool, num_chunks, 1, [&](size_t b, size_t e) {
    for (size_t k = b; k < e; ++k) {
      const size_t first = column_begin_[k * kColumnGrain];
      const size_t last = column_begin_[std::min(num_columns, (k + 1) * kColumnGrain)];
      const uint32_t begin = grid->adjacency_offsets[first];
      std::copy_n(chunk_nbr_[k].begin(), grid->adjacency_offsets[last] - begin,
                  grid->adjacency.begin() + begin);
    }
  });
}

void Voxelizer::ComputeNormals(VoxelGrid* grid) const {
  core::ThreadPool* const pool = pool_;
  CLUTTERSEG_DEMAND(grid != nullptr);
  const size_t num_voxels = grid->size();
  CLUTTERSEG_DEMAND(grid->adjacency_offsets.size() == num_voxels + 1);
  grid->normal.resize(num_voxels);
  grid->curvature.resize(num_voxels);
  ForChunks(pool, num_voxels, kVoxelGrain, [&](size_t b, size_t e) {
    // Covariances of a block of voxels first, then their eigen-analyses together.
    constexpr size_t kBlock = 64;
    double cov[kBlock][6], nrm[kBlock][3], l[kBlock][3];
    uint32_t block_voxel[kBlock];
    for (size_t block = b; block < e; block += kBlock) {
      size_t count = 0;
      for (size_t v = block; v < std::min(e, block + kBlock); ++v) {
        const core::Vec3f& c0 = grid->centroid[v];
        const uint32_t begin = grid->adjacency_offsets[v];
        const uint32_t end = grid->adjacency_offsets[v + 1];
        if (end - begin < 2) {
          const float len = std::sqrt(c0.x * c0.x + c0.y * c0.y + c0.z * c0.z);
          grid->normal[v] = len > 0.f ? core::Vec3f{-c0.x / len, -c0.y / len, -c0.z / len}
                                      : core::Vec3f{0.f, 0.f, -1.f};
          grid->curvature[v] = 1.0f / 3.0f;
          continue;
        }
        // Weighted moments relative to the voxel's own centroid, so that single precision is
        // accurate (offsets are a few voxels).
        float w_sum = static_cast<float>(grid->num_points[v]);
        float m[3] = {0.f, 0.f, 0.f};
        float s[6] = {0.f, 0.f, 0.f, 0.f, 0.f, 0.f};
        for (uint32_t k = begin; k < end; ++k) {
          const uint32_t j = grid->adjacency[k];
          const core::Vec3f& c = grid->centroid[j];
          const float w = static_cast<float>(grid->num_points[j]);
          const float dx = c.x - c0.x, dy = c.y - c0.y, dz = c.z - c0.z;
          const float wx = w * dx, wy = w * dy, wz = w * dz;
          w_sum += w;
          m[0] += wx;
          m[1] += wy;
          m[2] += wz;
          s[0] += wx * dx;
          s[1] += wx * dy;
          s[2] += wx * dz;
          s[3] += wy * dy;
          s[4] += wy * dz;
          s[5] += wz * dz;
        }
        const float inv = 1.0f / w_sum;
        const float mx = m[0] * inv, my = m[1] * inv, mz = m[2] * inv;
        double* out = cov[count];
        out[0] = s[0] * inv - mx * mx;
        out[1] = s[1] * inv - mx * my;
        out[2] = s[2] * inv - mx * mz;
        out[3] = s[3] * inv - my * my;
        out[4] = s[4] * inv - my * mz;
        out[5] = s[5] * inv - mz * mz;
        block_voxel[count++] = static_cast<uint32_t>(v);
      }
      SmallestEigenvectors(count, cov, nrm, l);
      for (size_t k = 0; k < count; ++k) {
        const uint32_t v = block_voxel[k];
        const core::Vec3f& c0 = grid->centroid[v];
        double* n = nrm[k];
        if (n[0] * c0.x + n[1] * c0.y + n[2] * c0.z > 0.0) {
          n[0] = -n[0];
          n[1] = -n[1];
          n[2] = -n[2];
        }
        grid->normal[v] = core::Vec3f{static_cast<float>(n[0]), static_cast<float>(n[1]),
                                      static_cast<float>(n[2])};
        const double total = l[k][0] + l[k][1] + l[k][2];
        grid->curvature[v] = total > 0.0 ? static_cast<float>(l[k][2] / total) : 0.0f;
      }
    }
  });
}

void Voxelizer::Compute(const core::PointCloud& cloud, bool mean_color, VoxelGrid* grid) {
  Voxelize(cloud, mean_color, grid);
  ComputeAdjacency(grid);
  ComputeNormals(grid);
}

}  // namespace clutterseg::geometry
