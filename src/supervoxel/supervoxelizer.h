#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"
#include "clutterseg/geometry/key_index_map.h"
#include "clutterseg/geometry/voxel_grid.h"
#include "clutterseg/supervoxel/supervoxel_params.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::supervoxel {

/// VCCS supervoxels (Papon et al. 2013; docs/method.md section 1) over an octree-leaf voxel
/// grid, with two guarantees PCL's implementation lacks: every valid voxel (hence every finite
/// point within range) belongs to a supervoxel, and every supervoxel's voxels form one
/// connected component of the 26-neighbourhood voxel graph.
///
/// Steps: (1) voxelize, 26-adjacency, voxel normals (geometry::Voxelizer). (2) Seeds: per
/// occupied seed_resolution_m cell (Euclidean, camera frame) the voxel nearest the cell centre;
/// kept when the voxels reachable through the voxel graph within seed_resolution_m / 2 number
/// at least min_seed_occupancy * pi r^2 / s^2, s the voxel edge at the seed's depth; then
/// moved to the lowest-curvature voxel of its 26-neighbourhood (duplicates merged).
/// (3) Growth, ceil(1.8 * seed_resolution_m / s_min) layers (s_min the voxel edge at the
/// nearest seed): every supervoxel in turn expands its last layer; a voxel joins when its
/// distance D^2 = wc * Dc^2 / 255^2 + ws * Ds^2 / (3 R^2) + wn * (1 - |n . n_c|)^2 to the
/// supervoxel's centre is lower than that of its current owner (Dc: RGB distance, 0..255 per
/// channel; Ds: metres; R = seed_resolution_m). (4) refinement_iterations times: centre = mean
/// of member points and normals (colours), seed = member voxel nearest the centre, regrow.
/// (5) Voxels cut off from their supervoxel's seed are released; released and unreached
/// voxels join, layer by layer, the cheapest supervoxel of an already labelled neighbour;
/// components without any labelled voxel become supervoxels of their own.
///
/// Supervoxel ids: seeded supervoxels first, in ascending voxel-key order of their initial
/// (moved) seed voxel, then supervoxels of voxel components no seed reached, in ascending
/// voxel-key order of their first voxel.
///
/// Thread-safety: Compute must not run concurrently on one instance (it reuses internal
/// buffers, so nothing is allocated after the first frames); distinct instances are
/// independent. Work inside Compute is split over the pool given at construction so that
/// the output is bit-identical for any pool size, including no pool.
class Supervoxelizer {
 public:
  /// `pool` may be null (single-threaded) and must outlive the Supervoxelizer.
  /// @throws std::invalid_argument when `params` is invalid.
  explicit Supervoxelizer(const SupervoxelParams& params, core::ThreadPool* pool = nullptr);

  const SupervoxelParams& params() const { return params_; }

  /// Segments `cloud` (metres, camera frame; organized or not; NaN = invalid) into
  /// supervoxels, overwriting `out` (whose buffers are reused), with the time of each step
  /// in out->timings.
  void Compute(const core::PointCloud& cloud, Supervoxels* out);

  /// The voxel grid of the last Compute (positions in metres, camera frame).
  const geometry::VoxelGrid& voxels() const { return grid_; }
  /// Supervoxel id of each voxel of voxels() for the last Compute (all >= 0).
  const std::vector<int32_t>& voxel_label() const { return owner_; }
  /// Number of seeds that survived the occupancy filter in the last Compute.
  size_t num_seeds() const { return num_seeds_; }

 private:
  // Sizes chunk_queue_ and chunk_marks_ for `num_chunks` chunks over the current voxels.
  void PrepareChunkScratch(size_t num_chunks);
  void SelectSeeds();
  void SplitRegions();
  void Grow(int max_layers);
  void GrowRegion(size_t r, int max_layers);
  void Recenter();
  void RecenterRegion(size_t r);
  void EnforceConnectivity();
  void AssignLeftovers();
  void FillOutput(const core::PointCloud& cloud, Supervoxels* out);
  float Cost(uint32_t sv, uint32_t voxel) const;

  struct VoxelFeature {
    core::Vec3f centroid;
    core::Vec3f normal;
  };

  const SupervoxelParams params_;
  core::ThreadPool* const pool_;
  geometry::Voxelizer voxelizer_;
  geometry::VoxelGrid grid_;
  size_t num_seeds_{0};
  bool capped_{false};  // the last frame's seeds were thinned to max_supervoxels
  bool use_color_{false};
  float spatial_weight_{0.f};  // ws / (3 R^2)
  float color_weight_{0.f};    // wc / m^2

  // Seeding. Seed cells in first-offer order, each with the voxel nearest its centre.
  struct SeedCells {
    geometry::KeyIndexMap map;  // cell key -> index into the arrays below
    std::vector<uint64_t> key;
    std::vector<uint32_t> voxel;
    std::vector<float> dist;  // squared distance of `voxel` to the cell centre, m^2
    void Clear(size_t expected_cells);
    // Keeps `v` for cell `k` when the cell is new or `d` is strictly smaller than its best.
    void Offer(uint64_t k, uint32_t v, float d);
  };
  std::vector<SeedCells> chunk_cells_;  // per chunk of voxels
  SeedCells seed_cells_;                // all chunks merged in voxel order
  std::vector<uint32_t> candidates_;
  std::vector<uint8_t> candidate_keep_;
  // Per chunk of work: visit marks over the voxels, all zero between uses, and a queue used up
  // to a count (SelectSeeds, EnforceConnectivity; FillOutput reuses the queues as scratch).
  std::vector<std::vector<uint8_t>> chunk_marks_;
  std::vector<std::vector<uint32_t>> chunk_queue_;

  // Growth. Supervoxel s has seed seed_[s] and centre centre_*[s].
  std::vector<uint32_t> seed_;
  std::vector<core::Vec3f> centre_xyz_;
  std::vector<core::Vec3f> centre_normal_;
  std::vector<core::Vec3f> centre_color_;
  std::vector<VoxelFeature> feature_;
  struct Claim {
    int32_t owner;  // supervoxel, -1 = none
    float cost;     // its distance D^2, infinity when unclaimed
  };
  std::vector<Claim> claim_;
  std::vector<int32_t> owner_;
  std::vector<std::pair<uint32_t, uint32_t>> frontier_;
  std::vector<std::pair<uint32_t, uint32_t>> next_frontier_;
  // Growth regions: voxels [region_voxel_[r], region_voxel_[r + 1]) and supervoxels
  // [region_sv_[r], region_sv_[r + 1]); one more entry than regions.
  std::vector<uint32_t> region_voxel_;
  std::vector<uint32_t> region_sv_;
  // Grow's frontiers per region, used up to a count (they never shrink).
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> grow_frontier_;
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> grow_next_;
  std::vector<double> accum_;
  std::vector<float> best_dist_;
  std::vector<uint32_t> queue_;
  std::vector<uint8_t> mark_;
  std::vector<int32_t> pending_;

  // Output: voxels grouped by supervoxel, neighbour lists per chunk of supervoxels.
  std::vector<uint32_t> member_offsets_;
  std::vector<uint32_t> members_;
  std::vector<uint32_t> nbr_count_;
  std::vector<std::vector<uint32_t>> chunk_list_;
};

}  // namespace clutterseg::supervoxel
