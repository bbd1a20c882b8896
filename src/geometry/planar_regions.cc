#include "clutterseg/geometry/planar_regions.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/scoped_timer.h"
#include "clutterseg/core/simd_points.h"
#include "clutterseg/geometry/moments.h"

namespace clutterseg::geometry {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr size_t kRowGrain = 32;    // rows per band of the pixel passes
constexpr size_t kCellGrain = 256;  // cells per chunk of the cell fits

#if defined(__SSE2__)
// The moments (AddToMoments) of the valid points (z not NaN) among the n pixels at `a` and
// the n pixels at `b`, into `sa` and `sb` (kNumMoments values each, overwritten): the two
// runs in the two lanes of SSE2 registers, point by point in pixel order, each lane doing the
// scalar additions and products in the same order, so that the sums are bit-identical to
// AddToMoments over the valid points. An invalid pixel adds +0.0 instead of being skipped,
// which changes no sum (a sum that starts at +0.0 never becomes -0.0).
void MomentsOfTwoRuns(const core::Vec3f* a, const core::Vec3f* b, size_t n, double* sa,
                      double* sb) {
  __m128d m[kNumMoments];
  for (__m128d& x : m) x = _mm_setzero_pd();
  const __m128d one = _mm_set1_pd(1.0);
  for (size_t u = 0; u < n; ++u) {
    const __m128d z = _mm_cvtps_pd(_mm_unpacklo_ps(_mm_load_ss(&a[u].z), _mm_load_ss(&b[u].z)));
    const __m128d valid = _mm_cmpord_pd(z, z);
    const __m128d x = _mm_and_pd(
        valid, _mm_cvtps_pd(_mm_unpacklo_ps(_mm_load_ss(&a[u].x), _mm_load_ss(&b[u].x))));
    const __m128d y = _mm_and_pd(
        valid, _mm_cvtps_pd(_mm_unpacklo_ps(_mm_load_ss(&a[u].y), _mm_load_ss(&b[u].y))));
    const __m128d zv = _mm_and_pd(valid, z);
    m[0] = _mm_add_pd(m[0], _mm_and_pd(valid, one));
    m[1] = _mm_add_pd(m[1], x);
    m[2] = _mm_add_pd(m[2], y);
    m[3] = _mm_add_pd(m[3], zv);
    m[4] = _mm_add_pd(m[4], _mm_mul_pd(x, x));
    m[5] = _mm_add_pd(m[5], _mm_mul_pd(x, y));
    m[6] = _mm_add_pd(m[6], _mm_mul_pd(x, zv));
    m[7] = _mm_add_pd(m[7], _mm_mul_pd(y, y));
    m[8] = _mm_add_pd(m[8], _mm_mul_pd(y, zv));
    m[9] = _mm_add_pd(m[9], _mm_mul_pd(zv, zv));
  }
  for (int k = 0; k < kNumMoments; ++k) {
    _mm_store_sd(sa + k, m[k]);
    _mm_storeh_pd(sb + k, m[k]);
  }
}
#endif

// Shifts a row of `words` 64-bit words (bit u % 64 of word u / 64 is pixel u) by s < 64
// pixels towards higher u (up = true) or lower u, ORing the result into `out`.
inline void OrShifted(const uint64_t* in, size_t words, size_t s, bool up, uint64_t* out) {
  if (s == 0) return;
  for (size_t k = 0; k < words; ++k) {
    uint64_t x;
    if (up) {
      x = in[k] << s;
      if (k > 0) x |= in[k - 1] >> (64 - s);
    } else {
      x = in[k] >> s;
      if (k + 1 < words) x |= in[k + 1] << (64 - s);
    }
    out[k] |= x;
  }
}

// Calls fn(word, mask) for each word of a bit row that pixels [begin, end) touch, with the
// mask of their bits in it.
template <typename Fn>
inline void ForRangeWords(size_t begin, size_t end, const Fn& fn) {
  for (size_t k = begin / 64; k * 64 < end; ++k) {
    uint64_t mask = ~uint64_t{0};
    if (k * 64 < begin) mask &= ~uint64_t{0} << (begin - k * 64);
    if (end < (k + 1) * 64) mask &= ~(~uint64_t{0} << (end - k * 64));
    fn(k, mask);
  }
}

// Box dilation of a bit image (h rows of (w + 63) / 64 words): a bit of `out` is set when a
// bit of `in` lies within m pixels in x and in y; bands of rows on `pool` (the same bits
// for any pool). `rows` and `lines` (a row per band) are scratch.
void DilateBits(core::ThreadPool* pool, size_t w, size_t h, size_t m,
                const std::vector<uint64_t>& in, std::vector<uint64_t>* rows,
                std::vector<uint64_t>* lines, std::vector<uint64_t>* out) {
  const size_t words = (w + 63) / 64;
  rows->resize(words * h);
  lines->resize(words * core::ThreadPool::NumChunks(h, kRowGrain));
  core::ForChunks(pool, h, kRowGrain, [&](size_t v0, size_t v1) {
    uint64_t* const line = lines->data() + (v0 / kRowGrain) * words;
    for (size_t v = v0; v < v1; ++v) {
      const uint64_t* const src = in.data() + v * words;
      uint64_t* const row = rows->data() + v * words;
      std::copy(src, src + words, row);
      // Radius r grown by s <= r + 1 each step: the shifted copies leave no gap.
      for (size_t r = 0; r < m;) {
        const size_t s = std::min({r + 1, m - r, size_t{63}});
        std::copy(row, row + words, line);
        OrShifted(line, words, s, true, row);
        OrShifted(line, words, s, false, row);
        r += s;
      }
    }
  });
  out->resize(words * h);
  core::ForChunks(pool, h, kRowGrain, [&](size_t v0, size_t v1) {
    for (size_t v = v0; v < v1; ++v) {
      uint64_t* const dst = out->data() + v * words;
      std::fill(dst, dst + words, uint64_t{0});
      const size_t first = v >= m ? v - m : 0, last = std::min(h - 1, v + m);
      for (size_t q = first; q <= last; ++q) {
        const uint64_t* const src = rows->data() + q * words;
        for (size_t k = 0; k < words; ++k) dst[k] |= src[k];
      }
    }
  });
}

inline float Dot(const core::Vec3f& a, const core::Vec3f& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

// |n . p + d|, summed as the four-lane path of step 4 sums it (the same value either way).
inline float PlaneDistance(float nx, float ny, float nz, float d, const core::Vec3f& p) {
  return std::abs((nx * p.x + ny * p.y) + (nz * p.z + d));
}

// Metric area of a pixel at `p` on a surface of normal `n`: z^2 / (fx fy cos t), the
// incidence cosine clamped like the refinement's plane areas.
inline double PixelArea(const core::Vec3f& p, const core::Vec3f& n, double pixel_area) {
  const double r = std::sqrt(double(p.x) * p.x + double(p.y) * p.y + double(p.z) * p.z);
  if (!(r > 0.0)) return 0.0;
  const double cos_t = std::max(0.2, std::abs(double(Dot(p, n))) / r);
  return double(p.z) * p.z * pixel_area / cos_t;
}

// Plane through the points of moments `m` (count > 0), normal towards the camera.
inline void FitMoments(const double* m, core::Vec3f* normal, float* d) {
  ShapeSummary s;
  SummarizeMoments(m, &s);
  *normal = s.normal;
  *d = -Dot(s.normal, s.centroid);
}

// RMS distance to the plane n . p + d = 0 of the points of moments `m` (count > 0), from the
// moments: E[(n . p + d)^2] = n^T E[p p^T] n + 2 d n . E[p] + d^2.
inline double PlaneRms(const double* m, const core::Vec3f& n, float d) {
  const double nx = n.x, ny = n.y, nz = n.z, dd = d;
  const double second = nx * nx * m[4] + 2 * nx * ny * m[5] + 2 * nx * nz * m[6] + ny * ny * m[7] +
                        2 * ny * nz * m[8] + nz * nz * m[9];
  const double first = nx * m[1] + ny * m[2] + nz * m[3];
  const double mse = (second + 2 * dd * first) / m[0] + dd * dd;
  return std::sqrt(std::max(0.0, mse));
}

}  // namespace

void PlanarRegionParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("cell_px", cell_px, 4, 128, "px");
  check.InRange("min_valid_fraction", min_valid_fraction, 0.1f, 1.f);
  check.InRange("max_rms_at_1m_m", max_rms_at_1m_m, 1e-5f, 0.1f, "m");
  check.InRange("min_rms_m", min_rms_m, 0.f, 0.1f, "m");
  check.InRange("max_normal_angle_deg", max_normal_angle_deg, 0.1f, 45.f, "deg");
  check.InRange("max_region_rms", max_region_rms, 0.1f, 100.f);
  check.InRange("margin_px", margin_px, 0, 256, "px");
  check.InRange("ring_min_cluster_px", ring_min_cluster_px, 0, 1 << 20, "px");
  check.InRange("max_point_distance_rms", max_point_distance_rms, 0.1f, 100.f);
}

void PlanarRegionFinder::DropSmallIslands(size_t w, size_t h, uint32_t min_object_pixels) {
  if (min_object_pixels == 0) return;
  const size_t words = (w + 63) / 64;
  // The kept pixels: object points, and support points in the ring.
  kept_bits_.resize(words * h);
  for (size_t k = 0; k < words * h; ++k) {
    kept_bits_[k] = object_bits_[k] | (support_bits_[k] & ring_bits_[k]);
  }
  // Their runs, row by row, and a union-find forest over the runs (8-connected: runs of
  // neighbouring rows that overlap or touch diagonally are one island).
  runs_.clear();
  run_row_start_.assign(h + 1, 0);
  for (size_t v = 0; v < h; ++v) {
    run_row_start_[v] = static_cast<uint32_t>(runs_.size());
    const uint64_t* const row = &kept_bits_[v * words];
    size_t u = 0;
    while (u < w) {
      size_t k = u / 64;  // the next set bit at or after u
      uint64_t x = row[k] & (~uint64_t{0} << (u % 64));
      while (x == 0 && ++k < words) x = row[k];
      if (x == 0) break;
      const size_t begin = k * 64 + static_cast<size_t>(__builtin_ctzll(x));
      if (begin >= w) break;
      k = begin / 64;  // the next clear bit after it
      uint64_t y = ~row[k] & (~uint64_t{0} << (begin % 64));
      while (y == 0 && ++k < words) y = ~row[k];
      const size_t end = y == 0 ? w : std::min(w, k * 64 + static_cast<size_t>(__builtin_ctzll(y)));
      runs_.push_back(Run{static_cast<uint32_t>(begin), static_cast<uint32_t>(end),
                          static_cast<uint32_t>(runs_.size())});
      u = end;
    }
  }
  run_row_start_[h] = static_cast<uint32_t>(runs_.size());
  auto find = [&](uint32_t x) {
    while (runs_[x].parent != x) {
      runs_[x].parent = runs_[runs_[x].parent].parent;
      x = runs_[x].parent;
    }
    return x;
  };
  for (size_t v = 1; v < h; ++v) {
    uint32_t a = run_row_start_[v - 1];
    const uint32_t a_end = run_row_start_[v];
    for (uint32_t b = run_row_start_[v]; b < run_row_start_[v + 1]; ++b) {
      // Runs of the row above that end before this one begins (less the diagonal) are done.
      while (a < a_end && runs_[a].end < runs_[b].begin) ++a;
      for (uint32_t c = a; c < a_end && runs_[c].begin <= runs_[b].end; ++c) {
        const uint32_t ra = find(c), rb = find(b);
        if (ra != rb) runs_[std::max(ra, rb)].parent = std::min(ra, rb);
      }
    }
  }
  // Object points per island.
  island_objects_.assign(runs_.size(), 0);
  for (size_t v = 0; v < h; ++v) {
    const uint64_t* const object = &object_bits_[v * words];
    for (uint32_t r = run_row_start_[v]; r < run_row_start_[v + 1]; ++r) {
      uint32_t count = 0;
      ForRangeWords(runs_[r].begin, runs_[r].end, [&](size_t k, uint64_t mask) {
        count += static_cast<uint32_t>(__builtin_popcountll(object[k] & mask));
      });
      island_objects_[find(r)] += count;
    }
  }
  // Small islands leave the ring: their support points are taken.
  for (size_t v = 0; v < h; ++v) {
    uint64_t* const ring = &ring_bits_[v * words];
    for (uint32_t r = run_row_start_[v]; r < run_row_start_[v + 1]; ++r) {
      if (island_objects_[find(r)] >= min_object_pixels) continue;
      ForRangeWords(runs_[r].begin, runs_[r].end,
                    [&](size_t k, uint64_t mask) { ring[k] &= ~mask; });
    }
  }
}

PlanarRegionFinder::PlanarRegionFinder(const PlanarRegionParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

void PlanarRegionFinder::Compute(const core::CameraIntrinsics& intrinsics, float min_area_m2,
                                 core::PointCloud* cloud, PlanarRegions* out) {
  const core::ScopedTimer timer(&out->time_ms);
  out->regions.clear();
  out->num_taken_points = 0;
  out->taken_bits.clear();
  out->taken_words_per_row = 0;
  const size_t w = static_cast<size_t>(std::max(cloud->width, 0));
  const size_t h = static_cast<size_t>(std::max(cloud->height, 0));
  if (!params_.enabled || !cloud->organized() || w * h != cloud->xyz.size() || w == 0) return;

  // 1. Moments of the valid points of each cell, by rows of cells.
  const size_t c = static_cast<size_t>(params_.cell_px);
  const size_t cw = (w + c - 1) / c, ch = (h + c - 1) / c, num_cells = cw * ch;
  moments_.assign(num_cells * kNumMoments, 0.0);
  pixels_.resize(num_cells);
  core::Vec3f* const xyz = cloud->xyz.data();
  core::ForChunks(pool_, ch, 1, [&](size_t rb, size_t re) {
    for (size_t cr = rb; cr < re; ++cr) {
      double* const row = &moments_[cr * cw * kNumMoments];
      const size_t v_end = std::min(h, (cr + 1) * c);
      for (size_t cc = 0; cc < cw; ++cc) {
        pixels_[cr * cw + cc] =
            static_cast<uint32_t>((std::min(w, (cc + 1) * c) - cc * c) * (v_end - cr * c));
      }
      // Each cell's run of a pixel row is summed in registers, then added to the cell.
      for (size_t v = cr * c; v < v_end; ++v) {
        const core::Vec3f* const line = xyz + v * w;
        size_t cc = 0;
#if defined(__SSE2__)
        // Two full cells at a time (the same sums as the loop below).
        for (; (cc + 2) * c <= w; cc += 2) {
          double s[2][kNumMoments];
          MomentsOfTwoRuns(line + cc * c, line + (cc + 1) * c, c, s[0], s[1]);
          double* m = row + cc * kNumMoments;
          for (size_t k = 0; k < 2 * kNumMoments; ++k) m[k] += s[k / kNumMoments][k % kNumMoments];
        }
#endif
        for (; cc < cw; ++cc) {
          double s[kNumMoments] = {};
          const size_t u_end = std::min(w, (cc + 1) * c);
          for (size_t u = cc * c; u < u_end; ++u) {
            const core::Vec3f p = line[u];
            if (!(p.z == p.z)) continue;
            AddToMoments(p, s);
          }
          double* m = row + cc * kNumMoments;
          for (size_t k = 0; k < kNumMoments; ++k) m[k] += s[k];
        }
      }
    }
  });

  // 2. Planar cells: nearly full, and flat within the depth noise at their depth.
  cells_.assign(num_cells, Cell{});
  order_.clear();
  // The RMS bound at depth z: the sensor's noise floor, or its quadratic growth.
  auto bound_at = [&](double z) {
    return std::max(double{params_.min_rms_m}, double{params_.max_rms_at_1m_m} * z * z);
  };
  core::ForChunks(pool_, num_cells, kCellGrain, [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) {
      const double* m = &moments_[i * kNumMoments];
      Cell& cell = cells_[i];
      if (m[0] < std::max(3.0, double{params_.min_valid_fraction} * pixels_[i])) continue;
      ShapeSummary s;
      SummarizeMoments(m, &s);
      cell.centroid = s.centroid;
      cell.normal = s.normal;
      cell.rms_bound = static_cast<float>(bound_at(s.centroid.z));
      cell.flatness = std::sqrt(std::max(0.f, s.eigenvalues.z)) / cell.rms_bound;
      cell.planar = cell.flatness <= 1.f;
    }
  });
  for (size_t i = 0; i < num_cells; ++i) {
    if (cells_[i].planar) order_.push_back(static_cast<uint32_t>(i));
  }
  // Flattest cells seed first (ties by position): the table grows from its cleanest part.
  std::sort(order_.begin(), order_.end(), [&](uint32_t a, uint32_t b) {
    return cells_[a].flatness < cells_[b].flatness ||
           (cells_[a].flatness == cells_[b].flatness && a < b);
  });

  // 3. Regions: 4-connected planar cells that agree with the region's plane, refitted each
  // time the region doubles.
  cell_region_.assign(num_cells, -1);
  region_moments_.clear();
  const float min_cos = static_cast<float>(std::cos(params_.max_normal_angle_deg * kDegToRad));
  const double pixel_area = 1.0 / (intrinsics.fx * intrinsics.fy);
  size_t num_grown = 0;
  for (const uint32_t seed : order_) {
    if (cell_region_[seed] != -1) continue;
    const int32_t id = static_cast<int32_t>(num_grown++);
    region_moments_.resize(num_grown * kNumMoments, 0.0);
    double* rm = &region_moments_[size_t(id) * kNumMoments];
    core::Vec3f n = cells_[seed].normal;
    float d = -Dot(n, cells_[seed].centroid);
    size_t next_refit = 2;
    queue_.assign(1, seed);
    cell_region_[seed] = id;
    for (size_t q = 0; q < queue_.size(); ++q) {
      const uint32_t i = queue_[q];
      const double* m = &moments_[size_t{i} * kNumMoments];
      for (size_t k = 0; k < kNumMoments; ++k) rm[k] += m[k];
      if (q + 1 == next_refit) {
        FitMoments(rm, &n, &d);
        next_refit *= 2;
      }
      const size_t cr = i / cw, cc = i % cw;
      const size_t nbr[4] = {cc > 0 ? i - 1 : i, cc + 1 < cw ? i + 1 : i, cr > 0 ? i - cw : i,
                             cr + 1 < ch ? i + cw : i};
      for (const size_t j : nbr) {
        if (j == i || cell_region_[j] != -1 || !cells_[j].planar) continue;
        const Cell& cj = cells_[j];
        if (Dot(n, cj.normal) < min_cos) continue;
        if (PlaneRms(&moments_[j * kNumMoments], n, d) > params_.max_region_rms * cj.rms_bound) {
          continue;
        }
        cell_region_[j] = id;
        queue_.push_back(static_cast<uint32_t>(j));
      }
    }
  }

  // Regions of one plane that objects cut apart (a table between the objects, a floor behind
  // them) become one: both lie within their RMS bound of the plane fitted to the two
  // together. A region merges into the first (flattest-seeded) earlier root that passes, whose
  // moments and plane then include it, so a piece is judged against the plane of everything
  // merged so far, not against one small piece's fit; the order is fixed by the seeds.
  region_plane_.resize(num_grown);
  region_root_.resize(num_grown);
  for (size_t r = 0; r < num_grown; ++r) {
    FitMoments(&region_moments_[r * kNumMoments], &region_plane_[r].normal, &region_plane_[r].d);
    region_root_[r] = static_cast<int32_t>(r);
  }
  auto bound_of = [&](const double* m) {
    const double z = m[3] / m[0];
    return double{params_.max_region_rms} * bound_at(z);
  };
  for (size_t r = 1; r < num_grown; ++r) {
    const double* mr = &region_moments_[r * kNumMoments];
    if (mr[0] < 3.0) continue;
    for (size_t q = 0; q < r; ++q) {
      if (region_root_[q] != static_cast<int32_t>(q)) continue;
      double* const mq = &region_moments_[q * kNumMoments];
      if (Dot(region_plane_[q].normal, region_plane_[r].normal) < min_cos) continue;
      double both[kNumMoments];
      for (size_t k = 0; k < kNumMoments; ++k) both[k] = mq[k] + mr[k];
      RegionPlane joint;
      FitMoments(both, &joint.normal, &joint.d);
      if (PlaneRms(mr, joint.normal, joint.d) > bound_of(mr) ||
          PlaneRms(mq, joint.normal, joint.d) > bound_of(mq)) {
        continue;
      }
      region_root_[r] = static_cast<int32_t>(q);
      std::copy(both, both + kNumMoments, mq);
      region_plane_[q] = joint;
      break;
    }
  }
  // Kept regions: roots covering the support area (each root's plane is already the fit to
  // all its cells).
  region_out_.assign(num_grown, -1);
  region_area_.assign(num_grown, 0.0);
  for (size_t i = 0; i < num_cells; ++i) {
    if (cell_region_[i] < 0) continue;
    cell_region_[i] = region_root_[static_cast<size_t>(cell_region_[i])];
    const size_t r = static_cast<size_t>(cell_region_[i]);
    region_area_[r] += moments_[i * kNumMoments] *
                       PixelArea(cells_[i].centroid, region_plane_[r].normal, pixel_area);
  }
  for (size_t r = 0; r < num_grown; ++r) {
    if (region_root_[r] != static_cast<int32_t>(r) || region_area_[r] < min_area_m2) continue;
    region_out_[r] = static_cast<int32_t>(out->regions.size());
    PlanarRegion region;
    region.normal = region_plane_[r].normal;
    region.d = region_plane_[r].d;
    region.area_m2 = static_cast<float>(region_area_[r]);
    out->regions.push_back(region);
  }
  for (size_t i = 0; i < num_cells; ++i) {
    if (cell_region_[i] < 0) continue;
    cell_region_[i] = region_out_[static_cast<size_t>(cell_region_[i])];
    if (cell_region_[i] >= 0) ++out->regions[static_cast<size_t>(cell_region_[i])].num_cells;
  }
  if (out->regions.empty()) return;

  // 4. Per pixel: the points near a candidate plane of their cell (the cell's region, or the
  // regions nearest to a cell outside every region: one that failed the validity or
  // planarity test, a region's border, an object) are support; every other valid point is an
  // object point. The support points farther than margin_px (in x and in y) from every object
  // point go to their region: the ring of support around each object is measured from the
  // object's points, not from the cells it touches.
  const size_t num_regions = out->regions.size();
  // A region takes points only when it has a core cell (all 8 neighbours in it): planar
  // cells that noise scattered over the image can form a region of the support area, but
  // not a solid one.
  region_core_.assign(num_regions, 0);
  for (size_t i = 0; i < num_cells; ++i) {
    const int32_t r = cell_region_[i];
    const size_t cr = i / cw, cc = i % cw;
    if (r < 0 || cr == 0 || cc == 0 || cr + 1 == ch || cc + 1 == cw) continue;
    bool core = true;
    for (size_t nr = cr - 1; nr <= cr + 1 && core; ++nr) {
      for (size_t nc = cc - 1; nc <= cc + 1 && core; ++nc) core = cell_region_[nr * cw + nc] == r;
    }
    if (core) region_core_[static_cast<size_t>(r)] = 1;
  }
  // Candidates: a region's own cells, then every other cell those of the regions nearest to
  // it (in 8-connected steps over cells outside the regions; up to kMax, in region order).
  cell_candidates_.assign(num_cells, CellCandidates{});
  queue_.clear();
  for (size_t i = 0; i < num_cells; ++i) {
    const int32_t r = cell_region_[i];
    if (r < 0 || !region_core_[static_cast<size_t>(r)]) continue;
    CellCandidates& cand = cell_candidates_[i];
    cand.region[cand.count++] = static_cast<int16_t>(r);
    queue_.push_back(static_cast<uint32_t>(i));
  }
  cell_step_.assign(num_cells, UINT32_MAX);
  for (const uint32_t i : queue_) cell_step_[i] = 0;
  for (size_t q = 0; q < queue_.size(); ++q) {
    const uint32_t i = queue_[q];
    const CellCandidates& from = cell_candidates_[i];
    const size_t cr = i / cw, cc = i % cw;
    for (size_t nr = cr > 0 ? cr - 1 : 0; nr <= std::min(ch - 1, cr + 1); ++nr) {
      for (size_t nc = cc > 0 ? cc - 1 : 0; nc <= std::min(cw - 1, cc + 1); ++nc) {
        const size_t j = nr * cw + nc;
        if (cell_step_[j] != UINT32_MAX && cell_step_[j] != cell_step_[i] + 1) continue;
        if (cell_step_[j] == UINT32_MAX) {
          cell_step_[j] = cell_step_[i] + 1;
          queue_.push_back(static_cast<uint32_t>(j));
        }
        CellCandidates& to = cell_candidates_[j];
        for (uint8_t k = 0; k < from.count; ++k) {
          bool seen = false;
          for (uint8_t m = 0; m < to.count; ++m) seen = seen || to.region[m] == from.region[k];
          if (!seen && to.count < CellCandidates::kMax) to.region[to.count++] = from.region[k];
        }
      }
    }
  }
  // Candidates in region order, so that a point near two planes goes to the first.
  for (CellCandidates& cand : cell_candidates_) {
    std::sort(cand.region.begin(), cand.region.begin() + cand.count);
  }
  // The area of a taken pixel: at its cell's centroid (a cell spans a few centimetres).
  for (size_t i = 0; i < num_cells; ++i) {
    CellCandidates& cand = cell_candidates_[i];
    const double* const m = &moments_[i * kNumMoments];
    if (cand.count == 0 || m[0] <= 0.0) continue;
    const core::Vec3f centroid{static_cast<float>(m[1] / m[0]), static_cast<float>(m[2] / m[0]),
                               static_cast<float>(m[3] / m[0])};
    for (uint8_t k = 0; k < cand.count; ++k) {
      const core::Vec3f& normal = out->regions[static_cast<size_t>(cand.region[k])].normal;
      cand.pixel_area_m2[k] = static_cast<float>(PixelArea(centroid, normal, pixel_area));
    }
  }
  const size_t words = (w + 63) / 64;
  object_bits_.resize(words * h);
  support_bits_.resize(words * h);
  pixel_candidate_.resize(w * h);

  const float point_k = params_.max_point_distance_rms;
  const float rms_floor = params_.min_rms_m, rms_at_1m = params_.max_rms_at_1m_m;
  core::ForChunks(pool_, h, kRowGrain, [&](size_t v0, size_t v1) {
    for (size_t v = v0; v < v1; ++v) {
      const CellCandidates* const cell_row = &cell_candidates_[(v / c) * cw];
      const core::Vec3f* const line = xyz + v * w;
      uint8_t* const which = &pixel_candidate_[v * w];
      uint64_t* const support = &support_bits_[v * words];
      uint64_t* const object = &object_bits_[v * words];
      std::fill(support, support + words, uint64_t{0});
      std::fill(object, object + words, uint64_t{0});
      for (size_t cc = 0; cc < cw; ++cc) {
        const CellCandidates& cand = cell_row[cc];
        const size_t u1 = std::min(w, (cc + 1) * c);
        size_t u = cc * c;
        if (cand.count <= 1) {
          // None or one candidate region (the usual cells): the candidate is implied.
          const bool any = cand.count == 1;
          const PlanarRegion& pr = out->regions[any ? static_cast<size_t>(cand.region[0]) : 0];
          const float nx = pr.normal.x, ny = pr.normal.y, nz = pr.normal.z, d = pr.d;
          const float k = any ? point_k : -1.f;  // no candidate: no point is near
#if defined(__SSE2__)
          // Four points at a time, their bits written together (u is a multiple of 4).
          const __m128 vnx = _mm_set1_ps(nx), vny = _mm_set1_ps(ny), vnz = _mm_set1_ps(nz);
          const __m128 vd = _mm_set1_ps(d), vk = _mm_set1_ps(k);
          const __m128 vfloor = _mm_set1_ps(rms_floor), va = _mm_set1_ps(rms_at_1m);
          const __m128 sign = _mm_set1_ps(-0.f);
          for (; u % 4 == 0 && u + 4 <= u1; u += 4) {
            const core::FourPoints q = core::LoadFourPoints(line + u);
            const __m128 dot = _mm_add_ps(_mm_add_ps(_mm_mul_ps(vnx, q.x), _mm_mul_ps(vny, q.y)),
                                          _mm_add_ps(_mm_mul_ps(vnz, q.z), vd));
            const __m128 dist = _mm_andnot_ps(sign, dot);
            const __m128 limit =
                _mm_mul_ps(vk, _mm_max_ps(vfloor, _mm_mul_ps(va, _mm_mul_ps(q.z, q.z))));
            const __m128 near = _mm_cmple_ps(dist, limit);  // false for NaN
            const __m128 valid = _mm_cmpeq_ps(q.z, q.z);
            const uint64_t near_bits = static_cast<uint64_t>(_mm_movemask_ps(near));
            const uint64_t object_bits =
                static_cast<uint64_t>(_mm_movemask_ps(_mm_andnot_ps(near, valid)));
            support[u / 64] |= near_bits << (u % 64);
            object[u / 64] |= object_bits << (u % 64);
          }
#endif
          for (; u < u1; ++u) {
            const core::Vec3f& p = line[u];
            const float dist = PlaneDistance(nx, ny, nz, d, p);
            const bool near = dist <= k * std::max(rms_floor, rms_at_1m * (p.z * p.z));
            const uint64_t bit = uint64_t{1} << (u % 64);
            if (near) {
              support[u / 64] |= bit;
            } else if (p.z == p.z) {
              object[u / 64] |= bit;
            }
          }
          continue;
        }
        for (; u < u1; ++u) {
          const core::Vec3f& p = line[u];
          if (!(p.z == p.z)) continue;
          const float limit = point_k * std::max(rms_floor, rms_at_1m * (p.z * p.z));
          uint8_t k = 0;
          while (k < cand.count) {
            const PlanarRegion& pr = out->regions[static_cast<size_t>(cand.region[k])];
            if (PlaneDistance(pr.normal.x, pr.normal.y, pr.normal.z, pr.d, p) <= limit) break;
            ++k;
          }
          const uint64_t bit = uint64_t{1} << (u % 64);
          if (k < cand.count) {
            which[u] = static_cast<uint8_t>(k + 1);
            support[u / 64] |= bit;
          } else {
            object[u / 64] |= bit;
          }
        }
      }
    }
  });
  // The ring: within margin_px of the object points. A few points off the plane (noise
  // spikes on a far floor) would keep a square of 2 margin_px + 1 pixels of support around
  // each, an island that the later stages can take for an object: the support of a kept
  // island (8-connected object points and their ring) with fewer than ring_min_cluster_px
  // object points goes too (those points themselves stay in the cloud, and the supervoxels
  // drop them as tiny groups). Near an object, such points are part of its island.
  DilateBits(pool_, w, h, static_cast<size_t>(params_.margin_px), object_bits_, &row_bits_,
             &line_bits_, &ring_bits_);
  DropSmallIslands(w, h, static_cast<uint32_t>(params_.ring_min_cluster_px));
  const size_t num_bands = core::ThreadPool::NumChunks(h, kRowGrain);
  // Each band's counters on cache lines of their own (the bands run on different cores).
  const size_t stride = (num_regions + 7) / 8 * 8 + 8;
  band_taken_.assign(num_bands * stride, 0);
  band_area_.assign(num_bands * stride, 0.0);
  out->taken_words_per_row = words;
  out->taken_bits.assign(h * words, 0);
  core::ForChunks(pool_, h, kRowGrain, [&](size_t v0, size_t v1) {
    uint32_t* const taken = &band_taken_[(v0 / kRowGrain) * stride];
    double* const area = &band_area_[(v0 / kRowGrain) * stride];
    for (size_t v = v0; v < v1; ++v) {
      const uint64_t* const support = &support_bits_[v * words];
      const uint64_t* const near_object = &ring_bits_[v * words];
      const uint8_t* const which = &pixel_candidate_[v * w];
      uint64_t* const taken_row = &out->taken_bits[v * words];
      core::Vec3f* const line = xyz + v * w;
      const size_t cell_row = (v / c) * cw;
      for (size_t cc = 0; cc < cw; ++cc) {
        const CellCandidates& cand = cell_candidates_[cell_row + cc];
        if (cand.count == 0) continue;
        uint32_t count[CellCandidates::kMax] = {};
        const size_t u0 = cc * c, u1 = std::min(w, (cc + 1) * c);
        ForRangeWords(u0, u1, [&](size_t k, uint64_t mask) {
          uint64_t take = support[k] & ~near_object[k] & mask;
          taken_row[k] |= take;
          if (cand.count == 1) count[0] += static_cast<uint32_t>(__builtin_popcountll(take));
          for (; take != 0; take &= take - 1) {
            const size_t u = k * 64 + static_cast<size_t>(__builtin_ctzll(take));
            if (cand.count > 1) ++count[which[u] - 1];
            line[u] = core::Vec3f{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth};
          }
        });
        for (uint8_t k = 0; k < cand.count; ++k) {
          const size_t r = static_cast<size_t>(cand.region[k]);
          taken[r] += count[k];
          area[r] += count[k] * double{cand.pixel_area_m2[k]};
        }
      }
    }
  });
  // Summed in band order: the same totals for any pool.
  for (size_t b = 0; b < num_bands; ++b) {
    for (size_t r = 0; r < num_regions; ++r) {
      PlanarRegion& region = out->regions[r];
      region.num_taken_points += band_taken_[b * stride + r];
      region.taken_area_m2 += static_cast<float>(band_area_[b * stride + r]);
      out->num_taken_points += band_taken_[b * stride + r];
    }
  }
  // Regions that took nothing (no interior cell) are left to the supervoxels entirely.
  out->regions.erase(std::remove_if(out->regions.begin(), out->regions.end(),
                                    [](const PlanarRegion& r) { return r.num_taken_points == 0; }),
                     out->regions.end());
  // Largest first, ties in growth order: an insertion sort (a handful of regions; stable
  // without the temporary buffer std::stable_sort allocates).
  std::vector<PlanarRegion>& regions = out->regions;
  for (size_t i = 1; i < regions.size(); ++i) {
    for (size_t j = i; j > 0 && regions[j - 1].area_m2 < regions[j].area_m2; --j) {
      std::swap(regions[j - 1], regions[j]);
    }
  }
}

}  // namespace clutterseg::geometry
