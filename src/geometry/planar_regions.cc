#include "clutterseg/geometry/planar_regions.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "clutterseg/core/param_check.h"
#include "clutterseg/core/scoped_timer.h"
#include "clutterseg/geometry/moments.h"

namespace clutterseg::geometry {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr size_t kTakenBlockGrain = 64;

inline float Dot(const core::Vec3f& a, const core::Vec3f& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
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
  check.InRange("max_point_distance_rms", max_point_distance_rms, 0.1f, 100.f);
}

PlanarRegionFinder::PlanarRegionFinder(const PlanarRegionParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

void PlanarRegionFinder::Compute(const core::CameraIntrinsics& intrinsics, float min_area_m2,
                                 core::PointCloud* cloud, PlanarRegions* out) {
  const core::ScopedTimer timer(&out->time_ms);
  out->regions.clear();
  out->num_taken_points = 0;
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
        for (size_t cc = 0; cc < cw; ++cc) {
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
  for (size_t i = 0; i < num_cells; ++i) {
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
    if (cell.planar) order_.push_back(static_cast<uint32_t>(i));
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
  // them) become one: each lies within the RMS bound of the other's plane. Merged into the
  // earlier (flatter) region, in order, so the result does not depend on anything else.
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
      const double* mq = &region_moments_[q * kNumMoments];
      const RegionPlane& pq = region_plane_[q];
      const RegionPlane& pr = region_plane_[r];
      if (Dot(pq.normal, pr.normal) < min_cos) continue;
      if (PlaneRms(mr, pq.normal, pq.d) > bound_of(mr) ||
          PlaneRms(mq, pr.normal, pr.d) > bound_of(mq)) {
        continue;
      }
      region_root_[r] = static_cast<int32_t>(q);
      break;
    }
  }
  // Sum merged moments into the roots (roots come first, so one pass in order suffices).
  for (size_t r = 0; r < num_grown; ++r) {
    const size_t root = static_cast<size_t>(region_root_[r]);
    if (root == r) continue;
    for (size_t k = 0; k < kNumMoments; ++k) {
      region_moments_[root * kNumMoments + k] += region_moments_[r * kNumMoments + k];
    }
  }
  // Kept regions: roots covering the support area, refitted on all their cells.
  region_out_.assign(num_grown, -1);
  region_area_.assign(num_grown, 0.0);
  for (size_t r = 0; r < num_grown; ++r) {
    if (region_root_[r] == static_cast<int32_t>(r)) {
      FitMoments(&region_moments_[r * kNumMoments], &region_plane_[r].normal, &region_plane_[r].d);
    }
  }
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

  // 4. Blocks of half a cell whose surroundings up to margin_px pixels lie in one region (or
  // outside the image) give their points near the plane to it.
  const size_t half = (c + 1) / 2;
  const long margin = params_.margin_px;
  taken_blocks_.clear();
  for (size_t i = 0; i < num_cells; ++i) {
    const int32_t r = cell_region_[i];
    if (r < 0) continue;
    const size_t cr = i / cw, cc = i % cw;
    for (uint32_t q = 0; q < 4; ++q) {
      const long bu0 = static_cast<long>(cc * c + (q & 1) * half);
      const long bv0 = static_cast<long>(cr * c + (q >> 1) * half);
      const long bu1 = std::min(static_cast<long>(w), bu0 + static_cast<long>(half));
      const long bv1 = std::min(static_cast<long>(h), bv0 + static_cast<long>(half));
      if (bu0 >= bu1 || bv0 >= bv1) continue;
      const long lc = static_cast<long>(c);
      const long c0 = std::max(0L, bu0 - margin) / lc;
      const long c1 = std::min(static_cast<long>(w) - 1, bu1 - 1 + margin) / lc;
      const long r0 = std::max(0L, bv0 - margin) / lc;
      const long r1 = std::min(static_cast<long>(h) - 1, bv1 - 1 + margin) / lc;
      bool inside = true;
      for (long nr = r0; nr <= r1 && inside; ++nr) {
        for (long nc = c0; nc <= c1 && inside; ++nc) {
          inside = cell_region_[static_cast<size_t>(nr) * cw + static_cast<size_t>(nc)] == r;
        }
      }
      if (inside) taken_blocks_.push_back(static_cast<uint32_t>(i * 4 + q));
    }
  }
  block_taken_.assign(taken_blocks_.size(), 0);
  block_area_.assign(taken_blocks_.size(), 0.0);
  const float point_k = params_.max_point_distance_rms;
  core::ForChunks(pool_, taken_blocks_.size(), kTakenBlockGrain, [&](size_t b, size_t e) {
    for (size_t t = b; t < e; ++t) {
      const size_t i = taken_blocks_[t] / 4, q = taken_blocks_[t] % 4;
      const PlanarRegion& region = out->regions[static_cast<size_t>(cell_region_[i])];
      const size_t u0 = (i % cw) * c + (q & 1) * half, v0 = (i / cw) * c + (q >> 1) * half;
      const size_t u1 = std::min(w, u0 + half), v1 = std::min(h, v0 + half);
      uint32_t taken = 0;
      for (size_t v = v0; v < v1; ++v) {
        for (size_t u = u0; u < u1; ++u) {
          core::Vec3f& p = xyz[v * w + u];
          if (!(p.z == p.z)) continue;
          if (std::abs(Dot(region.normal, p) + region.d) > point_k * bound_at(p.z)) continue;
          ++taken;
          p = core::Vec3f{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth};
        }
      }
      // The area of the block's pixels, at its cell's centroid (a cell spans a few
      // centimetres).
      block_taken_[t] = taken;
      block_area_[t] = taken * PixelArea(cells_[i].centroid, region.normal, pixel_area);
    }
  });
  // Summed in block order: the same totals for any pool.
  for (size_t t = 0; t < taken_blocks_.size(); ++t) {
    PlanarRegion& region = out->regions[static_cast<size_t>(cell_region_[taken_blocks_[t] / 4])];
    region.num_taken_points += block_taken_[t];
    region.taken_area_m2 += static_cast<float>(block_area_[t]);
    out->num_taken_points += block_taken_[t];
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
