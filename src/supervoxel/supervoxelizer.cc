#include "clutterseg/supervoxel/supervoxelizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif

#include "clutterseg/core/assert.h"
#include "clutterseg/geometry/moments.h"

namespace clutterseg::supervoxel {
namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kInf = std::numeric_limits<float>::infinity();
// Colour distances (0..255 per channel) are divided by this normaliser m.
constexpr float kColorNormalizer = 255.f;
constexpr size_t kPointGrain = 16384;
constexpr size_t kMaxSeedChunks = 8;
constexpr size_t kSeedCellGrain = 4096;  // fewest voxels per chunk of the seed-cell pass

using Clock = std::chrono::steady_clock;

double Ms(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

using core::ForChunks;

inline float Dot(const core::Vec3f& a, const core::Vec3f& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

inline float Dist2(const core::Vec3f& a, const core::Vec3f& b) {
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}

inline core::Vec3f TowardsCamera(const core::Vec3f& c) {
  const float len = std::sqrt(Dot(c, c));
  return len > 0.f ? core::Vec3f{-c.x / len, -c.y / len, -c.z / len} : core::Vec3f{0.f, 0.f, -1.f};
}

inline uint64_t CellKey(const core::Vec3f& p, float inv_cell, int32_t* ix, int32_t* iy,
                        int32_t* iz) {
  constexpr int64_t kOffset = int64_t{1} << 20;
  *ix = static_cast<int32_t>(std::floor(p.x * inv_cell));
  *iy = static_cast<int32_t>(std::floor(p.y * inv_cell));
  *iz = static_cast<int32_t>(std::floor(p.z * inv_cell));
  const uint64_t mask = (uint64_t{1} << 21) - 1;
  return ((static_cast<uint64_t>(*ix + kOffset) & mask) << 42) |
         ((static_cast<uint64_t>(*iy + kOffset) & mask) << 21) |
         (static_cast<uint64_t>(*iz + kOffset) & mask);
}

#if defined(__SSE2__)
// A supervoxel centre broadcast to four lanes, for the costs of four voxels at once.
struct FourCentre {
  FourCentre(const core::Vec3f& c, const core::Vec3f& n, float spatial, float normal)
      : x(_mm_set1_ps(c.x)),
        y(_mm_set1_ps(c.y)),
        z(_mm_set1_ps(c.z)),
        nx(_mm_set1_ps(n.x)),
        ny(_mm_set1_ps(n.y)),
        nz(_mm_set1_ps(n.z)),
        ws(_mm_set1_ps(spatial)),
        wn(_mm_set1_ps(normal)) {}

  // ws |p - c|^2 + wn (1 - |n . cn|)^2 of voxels v[0..3] (features centroid, normal: six
  // floats each), evaluated like Dist2 and Dot: left to right, no fused operations.
  template <typename Feature>
  __m128 Costs(const Feature* feature, const uint32_t* v) const {
    static_assert(sizeof(Feature) == 6 * sizeof(float));
    const float* f0 = &feature[v[0]].centroid.x;
    const float* f1 = &feature[v[1]].centroid.x;
    const float* f2 = &feature[v[2]].centroid.x;
    const float* f3 = &feature[v[3]].centroid.x;
    __m128 px = _mm_loadu_ps(f0), py = _mm_loadu_ps(f1), pz = _mm_loadu_ps(f2),
           pw = _mm_loadu_ps(f3);  // x y z nx
    __m128 qx = _mm_loadu_ps(f0 + 2), qy = _mm_loadu_ps(f1 + 2), qz = _mm_loadu_ps(f2 + 2),
           qw = _mm_loadu_ps(f3 + 2);   // z nx ny nz
    _MM_TRANSPOSE4_PS(px, py, pz, pw);  // px = x, py = y, pz = z
    _MM_TRANSPOSE4_PS(qx, qy, qz, qw);  // qy = nx, qz = ny, qw = nz
    const __m128 dx = _mm_sub_ps(px, x), dy = _mm_sub_ps(py, y), dz = _mm_sub_ps(pz, z);
    const __m128 d2 =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    const __m128 dot =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(qy, nx), _mm_mul_ps(qz, ny)), _mm_mul_ps(qw, nz));
    const __m128 abs_dot = _mm_and_ps(dot, _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff)));
    const __m128 dn = _mm_sub_ps(_mm_set1_ps(1.f), abs_dot);
    return _mm_add_ps(_mm_mul_ps(ws, d2), _mm_mul_ps(_mm_mul_ps(wn, dn), dn));
  }

  __m128 x, y, z, nx, ny, nz, ws, wn;
};
#endif

}  // namespace

Supervoxelizer::Supervoxelizer(const SupervoxelParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool), voxelizer_(params.grid, pool) {
  const float r = params_.seed_resolution_m;
  spatial_weight_ = params_.spatial_importance / (3.f * r * r);
  color_weight_ = params_.color_importance / (kColorNormalizer * kColorNormalizer);
}

float Supervoxelizer::Cost(uint32_t sv, uint32_t voxel) const {
  const VoxelFeature& f = feature_[voxel];
  const float ds2 = Dist2(f.centroid, centre_xyz_[sv]);
  const float dn = 1.f - std::fabs(Dot(f.normal, centre_normal_[sv]));
  float d = spatial_weight_ * ds2 + params_.normal_importance * dn * dn;
  if (use_color_) d += color_weight_ * Dist2(grid_.mean_color[voxel], centre_color_[sv]);
  return d;
}

void Supervoxelizer::Compute(const core::PointCloud& cloud, Supervoxels* out) {
  CLUTTERSEG_DEMAND(out != nullptr);
  const Clock::time_point t0 = Clock::now();
  voxelizer_.Voxelize(cloud, params_.color_importance > 0.f, &grid_);
  const Clock::time_point t1 = Clock::now();
  voxelizer_.ComputeAdjacency(&grid_);
  const Clock::time_point t2 = Clock::now();
  voxelizer_.ComputeNormals(&grid_);
  const Clock::time_point t3 = Clock::now();
  use_color_ = params_.color_importance > 0.f && !grid_.mean_color.empty();
  // Growth reads a voxel's centroid and normal together: keep them in one cache line.
  feature_.resize(grid_.size());
  for (size_t v = 0; v < grid_.size(); ++v) {
    feature_[v] = VoxelFeature{grid_.centroid[v], grid_.normal[v]};
  }

  SelectSeeds();
  const Clock::time_point t4 = Clock::now();

  // Initial centres are the seed voxels themselves.
  const size_t num_seeds = seed_.size();
  centre_xyz_.resize(num_seeds);
  centre_normal_.resize(num_seeds);
  centre_color_.resize(num_seeds);
  float min_z = kInf;
  for (size_t s = 0; s < num_seeds; ++s) {
    const uint32_t v = seed_[s];
    centre_xyz_[s] = grid_.centroid[v];
    centre_normal_[s] = grid_.normal[v];
    centre_color_[s] = use_color_ ? grid_.mean_color[v] : core::Vec3f{};
    min_z = std::min(min_z, grid_.centroid[v].z);
  }
  // Enough layers to reach 1.8 seed spacings from the nearest seed (VCCS's search depth).
  int max_layers = 1;
  if (num_seeds > 0) {
    const float voxel = voxelizer_.VoxelSizeAt(std::max(min_z, 0.1f));
    max_layers = static_cast<int>(
        std::clamp(std::ceil(1.8f * params_.seed_resolution_m / voxel), 1.f, 1000.f));
  }
  SplitRegions();
  Grow(max_layers);
  for (int it = 0; it < params_.refinement_iterations; ++it) {
    Recenter();
    Grow(max_layers);
  }
  EnforceConnectivity();
  AssignLeftovers();
  const Clock::time_point t5 = Clock::now();

  FillOutput(cloud, out);
  const Clock::time_point t6 = Clock::now();
  out->timings.voxelize_ms = Ms(t0, t1);
  out->timings.adjacency_ms = Ms(t1, t2);
  out->timings.normals_ms = Ms(t2, t3);
  out->timings.seeding_ms = Ms(t3, t4);
  out->capped = capped_;
  out->timings.growth_ms = Ms(t4, t5);
  out->timings.output_ms = Ms(t5, t6);
}

void Supervoxelizer::PrepareChunkScratch(size_t num_chunks) {
  const size_t num_voxels = grid_.size();
  if (chunk_queue_.size() < num_chunks) chunk_queue_.resize(num_chunks);
  if (chunk_marks_.size() < num_chunks) chunk_marks_.resize(num_chunks);
  for (size_t k = 0; k < num_chunks; ++k) {
    if (chunk_marks_[k].size() < num_voxels) chunk_marks_[k].resize(num_voxels, 0);
  }
}

void Supervoxelizer::SeedCells::Clear(size_t expected_cells) {
  map.Clear(expected_cells);
  key.clear();
  voxel.clear();
  dist.clear();
}

void Supervoxelizer::SeedCells::Offer(uint64_t k, uint32_t v, float d) {
  bool inserted = false;
  const uint32_t index = map.FindOrInsert(k, static_cast<uint32_t>(voxel.size()), &inserted);
  if (inserted) {
    key.push_back(k);
    voxel.push_back(v);
    dist.push_back(d);
  } else if (d < dist[index]) {
    voxel[index] = v;
    dist[index] = d;
  }
}

void Supervoxelizer::SelectSeeds() {
  const size_t num_voxels = grid_.size();
  const float cell = params_.seed_resolution_m;
  const float inv_cell = 1.f / cell;

  // One candidate per occupied seed cell: the voxel nearest the cell centre (lowest index on
  // ties). Each chunk of voxels (fixed by the voxel count, not the pool) finds its own cells'
  // best voxels; the chunks are then merged in ascending voxel order, a later chunk winning a
  // cell only with a strictly smaller distance, which is the serial visit's result. Voxels are
  // in (x, y, z) key order, so the chunks are slabs that share few cells.
  const size_t cell_grain =
      std::max<size_t>(kSeedCellGrain, (num_voxels + kMaxSeedChunks - 1) / kMaxSeedChunks);
  const size_t num_cell_chunks = core::ThreadPool::NumChunks(num_voxels, cell_grain);
  if (chunk_cells_.size() < num_cell_chunks) chunk_cells_.resize(num_cell_chunks);
  ForChunks(pool_, num_voxels, cell_grain, [&](size_t b, size_t e) {
    SeedCells& cells = chunk_cells_[b / cell_grain];
    cells.Clear((e - b) / 8 + 16);
    for (size_t v = b; v < e; ++v) {
      const core::Vec3f& c = grid_.centroid[v];
      int32_t ix, iy, iz;
      const uint64_t key = CellKey(c, inv_cell, &ix, &iy, &iz);
      const core::Vec3f centre{(static_cast<float>(ix) + 0.5f) * cell,
                               (static_cast<float>(iy) + 0.5f) * cell,
                               (static_cast<float>(iz) + 0.5f) * cell};
      cells.Offer(key, static_cast<uint32_t>(v), Dist2(c, centre));
    }
  });
  seed_cells_.Clear(num_voxels / 8 + 16);
  for (size_t k = 0; k < num_cell_chunks; ++k) {
    const SeedCells& cells = chunk_cells_[k];
    for (size_t c = 0; c < cells.key.size(); ++c) {
      seed_cells_.Offer(cells.key[c], cells.voxel[c], cells.dist[c]);
    }
  }
  candidates_.assign(seed_cells_.voxel.begin(), seed_cells_.voxel.end());
  std::sort(candidates_.begin(), candidates_.end());

  // Occupancy: voxels within seed_resolution / 2 of the candidate, reached through the voxel
  // graph, against the count a flat disc through that ball would hold.
  const size_t num_candidates = candidates_.size();
  candidate_keep_.assign(num_candidates, 0);
  const size_t grain = std::max<size_t>(64, (num_candidates + kMaxSeedChunks - 1) / kMaxSeedChunks);
  PrepareChunkScratch(core::ThreadPool::NumChunks(num_candidates, grain));
  const float radius = 0.5f * params_.seed_resolution_m;
  const float radius2 = radius * radius;
  // The search stops as soon as the count is reached: only keep / drop is needed, and most
  // candidates lie on surfaces that reach it within a quarter of the disc.
  ForChunks(pool_, num_candidates, grain, [&](size_t b, size_t e) {
    std::vector<uint8_t>& marks = chunk_marks_[b / grain];
    std::vector<uint32_t>& queue = chunk_queue_[b / grain];
    for (size_t k = b; k < e; ++k) {
      const uint32_t seed = candidates_[k];
      const core::Vec3f& c = grid_.centroid[seed];
      const float voxel = voxelizer_.VoxelSizeAt(c.z);
      const float disc = kPi * radius2 / (voxel * voxel);
      const double needed = std::ceil(static_cast<double>(params_.min_seed_occupancy * disc));
      const size_t target = needed <= 1.0 ? 1 : static_cast<size_t>(std::min(needed, 1e9));
      // The queue is used up to `size` only and never shrinks (see FillOutput).
      if (queue.empty()) queue.resize(64);
      queue[0] = seed;
      size_t size = 1;
      marks[seed] = 1;
      for (size_t q = 0; q < size && size < target; ++q) {
        const uint32_t v = queue[q];
        // Branch-free, as in Grow: each neighbour is written, and kept when it joins.
        const uint32_t a_begin = grid_.adjacency_offsets[v], a_end = grid_.adjacency_offsets[v + 1];
        if (queue.size() < size + (a_end - a_begin)) {
          queue.resize(std::max(2 * queue.size(), size + (a_end - a_begin)));
        }
        uint32_t* out = queue.data();
        for (uint32_t a = a_begin; a < a_end; ++a) {
          const uint32_t n = grid_.adjacency[a];
          const bool near = Dist2(grid_.centroid[n], c) <= radius2;
          const uint8_t join = (marks[n] == 0) & near;
          marks[n] |= join;
          out[size] = n;
          size += join;
        }
      }
      for (size_t q = 0; q < size; ++q) marks[queue[q]] = 0;
      candidate_keep_[k] = size >= target ? 1 : 0;
    }
  });

  // Move each kept seed to the lowest-curvature voxel of its 26-neighbourhood.
  seed_.clear();
  for (size_t k = 0; k < num_candidates; ++k) {
    if (!candidate_keep_[k]) continue;
    uint32_t best = candidates_[k];
    float best_curv = grid_.curvature[best];
    const uint32_t v = candidates_[k];
    for (uint32_t a = grid_.adjacency_offsets[v]; a < grid_.adjacency_offsets[v + 1]; ++a) {
      const uint32_t n = grid_.adjacency[a];
      const float curv = grid_.curvature[n];
      if (curv < best_curv || (curv == best_curv && n < best)) {
        best = n;
        best_curv = curv;
      }
    }
    seed_.push_back(best);
  }
  std::sort(seed_.begin(), seed_.end());
  seed_.erase(std::unique(seed_.begin(), seed_.end()), seed_.end());
  const auto cap = static_cast<size_t>(params_.max_supervoxels);
  capped_ = seed_.size() > cap;
  if (capped_) {
    // Every k-th seed in voxel order, spread over the frame: seed i * size / cap.
    const size_t size = seed_.size();
    for (size_t i = 0; i < cap; ++i) seed_[i] = seed_[i * size / cap];
    seed_.resize(cap);
  }
  num_seeds_ = seed_.size();
}

void Supervoxelizer::SplitRegions() {
  // growth_regions strips of whole voxel columns' x (the image's columns under the camera
  // transform), of about equal voxel counts; supervoxel ids ascend with their seed voxels
  // (seed_ is sorted), so each region's supervoxels are a range too. The split depends on the
  // grid only, never on the pool.
  const size_t num_voxels = grid_.size();
  const size_t num_regions =
      std::max<size_t>(1, std::min<size_t>(static_cast<size_t>(params_.growth_regions),
                                           std::max<size_t>(1, seed_.size())));
  region_voxel_.assign(num_regions + 1, 0);
  region_sv_.assign(num_regions + 1, 0);
  for (size_t r = 1; r < num_regions; ++r) {
    size_t v = std::max<size_t>(r * num_voxels / num_regions, region_voxel_[r - 1]);
    while (v > 0 && v < num_voxels && grid_.coord[v].x == grid_.coord[v - 1].x) ++v;
    region_voxel_[r] = static_cast<uint32_t>(v);
    region_sv_[r] = static_cast<uint32_t>(
        std::lower_bound(seed_.begin(), seed_.end(), static_cast<uint32_t>(v)) - seed_.begin());
  }
  region_voxel_[num_regions] = static_cast<uint32_t>(num_voxels);
  region_sv_[num_regions] = static_cast<uint32_t>(seed_.size());
  if (grow_frontier_.size() < num_regions) grow_frontier_.resize(num_regions);
  if (grow_next_.size() < num_regions) grow_next_.resize(num_regions);
}

void Supervoxelizer::Grow(int max_layers) {
  const size_t num_voxels = grid_.size();
  claim_.assign(num_voxels, Claim{-1, kInf});
  const size_t num_regions = region_voxel_.size() - 1;
  ForChunks(pool_, num_regions, 1, [&](size_t b, size_t e) {
    for (size_t r = b; r < e; ++r) GrowRegion(r, max_layers);
  });
  owner_.resize(num_voxels);
  for (size_t v = 0; v < num_voxels; ++v) owner_[v] = claim_[v].owner;
}

void Supervoxelizer::GrowRegion(size_t r, int max_layers) {
  // The region's voxels are [lo, lo + span), its supervoxels [region_sv_[r], region_sv_[r + 1]);
  // only its own voxels are read or claimed, so regions grow independently.
  const uint32_t lo = region_voxel_[r];
  const uint32_t span = region_voxel_[r + 1] - lo;
  const size_t sv_begin = region_sv_[r], sv_end = region_sv_[r + 1];
  std::vector<std::pair<uint32_t, uint32_t>>& frontier = grow_frontier_[r];
  std::vector<std::pair<uint32_t, uint32_t>>& next_buf = grow_next_[r];
  Claim* claim = claim_.data();
  // The frontiers are used up to their counts only, so that they never shrink and the
  // branch-free loop below may write past the last entry it keeps.
  size_t frontier_size = sv_end - sv_begin;
  if (frontier.size() < frontier_size) frontier.resize(frontier_size);
  for (size_t s = sv_begin; s < sv_end; ++s) {
    claim[seed_[s]] = Claim{static_cast<int32_t>(s), 0.f};
    frontier[s - sv_begin] = {static_cast<uint32_t>(s), seed_[s]};
  }
  // One layer at a time, all supervoxels in turn (the frontier stays grouped by supervoxel in
  // ascending order). A voxel goes to whoever reaches it most cheaply; a supervoxel that loses
  // a voxel does not expand from it.
  const uint32_t* offsets = grid_.adjacency_offsets.data();
  const uint32_t* adjacency = grid_.adjacency.data();
  const VoxelFeature* feature = feature_.data();
  const float ws = spatial_weight_;
  const float wn = params_.normal_importance;
  // A local copy: the member would be reloaded after every frontier push.
  const bool use_color = use_color_;
  for (int layer = 0; layer < max_layers && frontier_size > 0; ++layer) {
    size_t next_size = 0;
    for (size_t f = 0; f < frontier_size; ++f) {
      const uint32_t s = frontier[f].first, v = frontier[f].second;  // captured below
      const int32_t label = static_cast<int32_t>(s);
      if (claim[v].owner != label) continue;
      const uint32_t begin = offsets[v], end = offsets[v + 1];
      if (next_buf.size() < next_size + (end - begin)) {
        next_buf.resize(std::max(2 * next_buf.size(), next_size + (end - begin)));
      }
      std::pair<uint32_t, uint32_t>* next = next_buf.data();
      if (use_color) {
        for (uint32_t a = begin; a < end; ++a) {
          const uint32_t n = adjacency[a];
          if (n - lo >= span) continue;
          Claim& cl = claim[n];
          if (cl.owner == label) continue;
          const float c = Cost(s, n);
          if (cl.cost <= c) continue;
          cl = Claim{label, c};
          next[next_size++] = {s, n};
        }
        continue;
      }
      // Without colour the loop is branch-free: which neighbours a supervoxel takes is data
      // dependent and mispredicts. A voxel the supervoxel already holds has exactly the cost
      // recomputed here (same centre, same voxel; 0 for the seed, which no cost undercuts), so
      // "strictly cheaper" alone also skips the supervoxel's own voxels. A neighbour outside
      // the region reads and rewrites v's own claim instead, unchanged.
      const core::Vec3f cx = centre_xyz_[s];
      const core::Vec3f cn = centre_normal_[s];
      auto offer = [&](uint32_t n, float c) {
        const bool inside = n - lo < span;
        const uint32_t m = inside ? n : v;
        const Claim cl = claim[m];
        // Unclaimed voxels cost infinity, so one comparison covers both cases.
        const bool take = inside & (c < cl.cost);
        claim[m] = take ? Claim{label, c} : cl;
        next[next_size] = {s, n};
        next_size += take ? 1 : 0;
      };
      uint32_t a = begin;
#if defined(__SSE2__)
      // Four neighbours' costs at once; each lane does the scalar cost's operations in the
      // same order, so the costs are bit-identical to it.
      const FourCentre centre(cx, cn, ws, wn);
      for (; a + 4 <= end; a += 4) {
        alignas(16) float c[4];
        _mm_store_ps(c, centre.Costs(feature, adjacency + a));
        for (int k = 0; k < 4; ++k) offer(adjacency[a + k], c[k]);
      }
#endif
      for (; a < end; ++a) {
        const uint32_t n = adjacency[a];
        const VoxelFeature& fe = feature[n];
        const float dn = 1.f - std::fabs(Dot(fe.normal, cn));
        offer(n, ws * Dist2(fe.centroid, cx) + wn * dn * dn);
      }
    }
    frontier.swap(next_buf);
    frontier_size = next_size;
    // Both buffers keep the larger size, so that which one a layer writes never matters for
    // allocation (none once the largest frame has been seen).
    if (next_buf.size() < frontier.size()) next_buf.resize(frontier.size());
  }
}

void Supervoxelizer::Recenter() {
  const size_t num_sv = seed_.size();
  constexpr size_t kStride = 10;
  accum_.assign(kStride * num_sv, 0.0);
  best_dist_.assign(num_sv, kInf);
  // A region's voxels belong to its own supervoxels only: regions are independent.
  const size_t num_regions = region_voxel_.size() - 1;
  ForChunks(pool_, num_regions, 1, [&](size_t rb, size_t re) {
    for (size_t r = rb; r < re; ++r) RecenterRegion(r);
  });
}

void Supervoxelizer::RecenterRegion(size_t r) {
  constexpr size_t kStride = 10;
  const size_t v_begin = region_voxel_[r], v_end = region_voxel_[r + 1];
  for (size_t v = v_begin; v < v_end; ++v) {
    const int32_t s = owner_[v];
    if (s < 0) continue;
    double* a = &accum_[kStride * static_cast<size_t>(s)];
    const double w = grid_.num_points[v];
    const double* ps = &grid_.point_sums[9 * v];
    const core::Vec3f& n = grid_.normal[v];
    a[0] += w;
    a[1] += ps[0];
    a[2] += ps[1];
    a[3] += ps[2];
    a[4] += w * n.x;
    a[5] += w * n.y;
    a[6] += w * n.z;
    if (use_color_) {
      const core::Vec3f& col = grid_.mean_color[v];
      a[7] += w * col.x;
      a[8] += w * col.y;
      a[9] += w * col.z;
    }
  }
  for (size_t s = region_sv_[r]; s < region_sv_[r + 1]; ++s) {
    const double* a = &accum_[kStride * s];
    CLUTTERSEG_DEMAND(a[0] > 0.0);  // a supervoxel always keeps its seed
    const double inv = 1.0 / a[0];
    centre_xyz_[s] = core::Vec3f{static_cast<float>(a[1] * inv), static_cast<float>(a[2] * inv),
                                 static_cast<float>(a[3] * inv)};
    const double len = std::sqrt(a[4] * a[4] + a[5] * a[5] + a[6] * a[6]);
    if (len > 0.0) {
      centre_normal_[s] =
          core::Vec3f{static_cast<float>(a[4] / len), static_cast<float>(a[5] / len),
                      static_cast<float>(a[6] / len)};
    }
    if (use_color_) {
      centre_color_[s] = core::Vec3f{static_cast<float>(a[7] * inv), static_cast<float>(a[8] * inv),
                                     static_cast<float>(a[9] * inv)};
    }
  }
  // The new seed is the member voxel nearest the centre (it stays in the region).
  for (size_t v = v_begin; v < v_end; ++v) {
    const int32_t s = owner_[v];
    if (s < 0) continue;
    const float d = Dist2(grid_.centroid[v], centre_xyz_[static_cast<size_t>(s)]);
    if (d < best_dist_[static_cast<size_t>(s)]) {
      best_dist_[static_cast<size_t>(s)] = d;
      seed_[static_cast<size_t>(s)] = static_cast<uint32_t>(v);
    }
  }
}

void Supervoxelizer::EnforceConnectivity() {
  // Voxels stolen during growth can cut a supervoxel apart: keep only the component of its
  // seed and release the rest.
  // Branch-free breadth-first search: every neighbour is written to the queue, which keeps it
  // only when it joins. Supervoxels are independent, so chunks of them run in parallel; each
  // chunk marks visits in scratch marks of its own (all zero between uses, as SelectSeeds
  // leaves them) and then writes mark_ for its supervoxels' kept voxels only.
  const size_t num_voxels = grid_.size();
  const size_t num_sv = seed_.size();
  mark_.assign(num_voxels, 0);
  const size_t grain = std::max<size_t>(64, (num_sv + kMaxSeedChunks - 1) / kMaxSeedChunks);
  PrepareChunkScratch(core::ThreadPool::NumChunks(num_sv, grain));
  const int32_t* owner = owner_.data();
  const uint32_t* offsets = grid_.adjacency_offsets.data();
  const uint32_t* adjacency = grid_.adjacency.data();
  ForChunks(pool_, num_sv, grain, [&](size_t b, size_t e) {
    // Used up to `size` only; room for one more neighbourhood is made before each visit.
    std::vector<uint32_t>& queue = chunk_queue_[b / grain];
    uint8_t* visited = chunk_marks_[b / grain].data();
    for (size_t s = b; s < e; ++s) {
      const int32_t label = static_cast<int32_t>(s);
      size_t size = 1;
      if (queue.empty()) queue.resize(1024);
      queue[0] = seed_[s];
      visited[seed_[s]] = 1;
      for (size_t q = 0; q < size; ++q) {
        const uint32_t v = queue[q];
        const uint32_t a_begin = offsets[v], a_end = offsets[v + 1];
        if (queue.size() < size + (a_end - a_begin)) {
          queue.resize(std::max(2 * queue.size(), size + (a_end - a_begin)));
        }
        uint32_t* out = queue.data();
        for (uint32_t a = a_begin; a < a_end; ++a) {
          const uint32_t n = adjacency[a];
          const uint8_t join = (visited[n] == 0) & (owner[n] == label);
          visited[n] |= join;
          out[size] = n;
          size += join;
        }
      }
      for (size_t q = 0; q < size; ++q) {
        visited[queue[q]] = 0;
        mark_[queue[q]] = 1;  // the supervoxel's own voxel: no other chunk writes it
      }
    }
  });
  for (size_t v = 0; v < num_voxels; ++v) {
    if (!mark_[v]) owner_[v] = -1;
  }
}

void Supervoxelizer::AssignLeftovers() {
  const size_t num_voxels = grid_.size();
  // mark_: 1 = labelled, 2 = queued, 0 = unlabelled (after EnforceConnectivity, mark_ is 1
  // exactly on labelled voxels).
  auto has_labelled_neighbour = [&](uint32_t v) {
    for (uint32_t a = grid_.adjacency_offsets[v]; a < grid_.adjacency_offsets[v + 1]; ++a) {
      if (owner_[grid_.adjacency[a]] >= 0) return true;
    }
    return false;
  };
  frontier_.clear();
  for (size_t v = 0; v < num_voxels; ++v) {
    if (owner_[v] < 0 && has_labelled_neighbour(static_cast<uint32_t>(v))) {
      mark_[v] = 2;
      frontier_.emplace_back(0, static_cast<uint32_t>(v));
    }
  }
  // Layered breadth-first fill: each layer joins the cheapest labelled neighbour's supervoxel,
  // decided on the labels of the previous layers only, so the result does not depend on the
  // order inside a layer. Joining a neighbour keeps supervoxels connected.
  while (!frontier_.empty()) {
    for (auto& [label, v] : frontier_) {
      float best_cost = kInf;
      int32_t best = -1;
      for (uint32_t a = grid_.adjacency_offsets[v]; a < grid_.adjacency_offsets[v + 1]; ++a) {
        const uint32_t n = grid_.adjacency[a];
        if (mark_[n] != 1) continue;
        const int32_t s = owner_[n];
        const float c = Cost(static_cast<uint32_t>(s), v);
        if (c < best_cost || (c == best_cost && s < best) || best < 0) {
          best_cost = c;
          best = s;
        }
      }
      CLUTTERSEG_DEMAND(best >= 0);
      label = static_cast<uint32_t>(best);
    }
    for (const auto& [label, v] : frontier_) owner_[v] = static_cast<int32_t>(label);
    next_frontier_.clear();
    for (const auto& [label, v] : frontier_) {
      mark_[v] = 1;
      for (uint32_t a = grid_.adjacency_offsets[v]; a < grid_.adjacency_offsets[v + 1]; ++a) {
        const uint32_t n = grid_.adjacency[a];
        if (mark_[n] != 0) continue;
        mark_[n] = 2;
        next_frontier_.emplace_back(0, n);
      }
    }
    frontier_.swap(next_frontier_);
    // Both buffers keep the larger capacity (see Grow).
    if (next_frontier_.capacity() < frontier_.capacity()) {
      next_frontier_.reserve(frontier_.capacity());
    }
  }
  // And the other way round: the next frame's first layer goes into frontier_.
  if (frontier_.capacity() < next_frontier_.capacity()) {
    frontier_.reserve(next_frontier_.capacity());
  }
  // Components no seed reached become supervoxels of their own.
  for (size_t v0 = 0; v0 < num_voxels; ++v0) {
    if (owner_[v0] >= 0) continue;
    const int32_t label = static_cast<int32_t>(seed_.size());
    seed_.push_back(static_cast<uint32_t>(v0));
    owner_[v0] = label;
    queue_.clear();
    queue_.push_back(static_cast<uint32_t>(v0));
    for (size_t q = 0; q < queue_.size(); ++q) {
      const uint32_t v = queue_[q];
      for (uint32_t a = grid_.adjacency_offsets[v]; a < grid_.adjacency_offsets[v + 1]; ++a) {
        const uint32_t n = grid_.adjacency[a];
        if (owner_[n] >= 0) continue;
        owner_[n] = label;
        queue_.push_back(n);
      }
    }
  }
}

void Supervoxelizer::FillOutput(const core::PointCloud& cloud, Supervoxels* out) {
  const size_t n = cloud.size();
  const size_t num_voxels = grid_.size();
  const size_t num_sv = seed_.size();
  out->width = cloud.width;
  out->height = cloud.height;
  out->pixel_label.resize(n);
  ForChunks(pool_, n, kPointGrain, [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) {
      const int32_t v = grid_.point_voxel[i];
      out->pixel_label[i] = v < 0 ? -1 : owner_[static_cast<size_t>(v)];
    }
  });

  // Voxels grouped by supervoxel (counting sort: ascending voxel order inside a group).
  member_offsets_.assign(num_sv + 1, 0);
  for (size_t v = 0; v < num_voxels; ++v) ++member_offsets_[static_cast<size_t>(owner_[v]) + 1];
  for (size_t s = 0; s < num_sv; ++s) member_offsets_[s + 1] += member_offsets_[s];
  members_.resize(num_voxels);
  queue_.assign(member_offsets_.begin(), member_offsets_.end() - 1);
  for (size_t v = 0; v < num_voxels; ++v) {
    members_[queue_[static_cast<size_t>(owner_[v])]++] = static_cast<uint32_t>(v);
  }

  // Per-supervoxel point moments (summed over its voxels in voxel order) and neighbour lists,
  // per chunk of supervoxels.
  constexpr size_t kStride = geometry::kNumMoments;
  constexpr size_t kSvGrain = 256;
  accum_.resize(kStride * num_sv);
  // Every chunk clears a last_seen table of num_sv entries, so the chunks are at most
  // kMaxSeedChunks: with a fixed grain a frame of noise (100k+ supervoxels of a voxel or two)
  // cost time and memory quadratic in num_sv (0.7 s and 300 MB for 640x480 random depths).
  const size_t list_grain = std::max(kSvGrain, (num_sv + kMaxSeedChunks - 1) / kMaxSeedChunks);
  const size_t num_sv_chunks = core::ThreadPool::NumChunks(num_sv, list_grain);
  if (chunk_queue_.size() < num_sv_chunks) chunk_queue_.resize(num_sv_chunks);
  if (chunk_list_.size() < num_sv_chunks) chunk_list_.resize(num_sv_chunks);
  nbr_count_.resize(num_sv);
  ForChunks(pool_, num_sv, list_grain, [&](size_t b, size_t e) {
    // last_seen (reusing a chunk's uint32 scratch) holds, per supervoxel, the last s + 1 that
    // listed it as a neighbour.
    std::vector<uint32_t>& last_seen = chunk_queue_[b / list_grain];
    // The list is used up to `size` only and never shrinks (no value-initialisation per
    // voxel; the branch-free loop may write past the entries it keeps).
    std::vector<uint32_t>& list = chunk_list_[b / list_grain];
    last_seen.assign(num_sv, 0);
    size_t size = 0;
    for (size_t s = b; s < e; ++s) {
      double* acc = &accum_[kStride * s];
      for (size_t k = 0; k < kStride; ++k) acc[k] = 0.0;
      const size_t list_begin = size;
      for (uint32_t m = member_offsets_[s]; m < member_offsets_[s + 1]; ++m) {
        const uint32_t v = members_[m];
        const double* ps = &grid_.point_sums[9 * static_cast<size_t>(v)];
        acc[0] += grid_.num_points[v];
        for (int k = 0; k < 9; ++k) acc[1 + k] += ps[k];
        // Branch-free: every neighbour's supervoxel is written after the list's end and kept
        // only when new (last_seen[s] is set too, which no other supervoxel's test reads as a
        // match).
        const uint32_t a_begin = grid_.adjacency_offsets[v], a_end = grid_.adjacency_offsets[v + 1];
        if (list.size() < size + (a_end - a_begin)) {
          list.resize(std::max(2 * list.size(), size + (a_end - a_begin)));
        }
        uint32_t* dst = list.data();
        const uint32_t mark = static_cast<uint32_t>(s + 1);
        for (uint32_t a = a_begin; a < a_end; ++a) {
          const uint32_t t = static_cast<uint32_t>(owner_[grid_.adjacency[a]]);
          const bool keep = (t != s) & (last_seen[t] != mark);
          last_seen[t] = mark;
          dst[size] = t;
          size += keep ? 1 : 0;
        }
      }
      std::sort(list.begin() + static_cast<std::ptrdiff_t>(list_begin),
                list.begin() + static_cast<std::ptrdiff_t>(size));
      nbr_count_[s] = static_cast<uint32_t>(size - list_begin);
    }
  });
  out->adjacency_offsets.resize(num_sv + 1);
  out->adjacency_offsets[0] = 0;
  for (size_t s = 0; s < num_sv; ++s) {
    out->adjacency_offsets[s + 1] = out->adjacency_offsets[s] + nbr_count_[s];
  }
  out->adjacency.resize(out->adjacency_offsets[num_sv]);
  for (size_t c = 0; c < num_sv_chunks; ++c) {
    const size_t first = c * list_grain, last = std::min(num_sv, first + list_grain);
    const uint32_t begin = out->adjacency_offsets[first];
    std::copy_n(chunk_list_[c].begin(), out->adjacency_offsets[last] - begin,
                out->adjacency.begin() + begin);
  }

  out->centroid.resize(num_sv);
  out->normal.resize(num_sv);
  out->curvature.resize(num_sv);
  out->eigenvalues.resize(num_sv);
  out->num_points.resize(num_sv);
  ForChunks(pool_, num_sv, kSvGrain, [&](size_t b, size_t e) {
    for (size_t s = b; s < e; ++s) {
      const double* a = &accum_[kStride * s];
      out->num_points[s] = static_cast<uint32_t>(a[0]);
      if (a[0] < 3.0) {
        const double inv = 1.0 / a[0];
        const core::Vec3f c{static_cast<float>(a[1] * inv), static_cast<float>(a[2] * inv),
                            static_cast<float>(a[3] * inv)};
        out->centroid[s] = c;
        out->normal[s] = TowardsCamera(c);
        out->curvature[s] = 0.f;
        out->eigenvalues[s] = core::Vec3f{};
        continue;
      }
      geometry::ShapeSummary shape;
      geometry::SummarizeMoments(a, &shape);
      out->centroid[s] = shape.centroid;
      out->normal[s] = shape.normal;
      out->curvature[s] = shape.curvature;
      out->eigenvalues[s] = shape.eigenvalues;
    }
  });
  // The moments go out with the supervoxels (patch features start from them).
  out->moments.assign(accum_.begin(),
                      accum_.begin() + static_cast<std::ptrdiff_t>(kStride * num_sv));
}

}  // namespace clutterseg::supervoxel
