#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/thread_pool.h"
#include "clutterseg/graph/linkage_params.h"
#include "clutterseg/graph/patch_features.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::graph {

/// Output of Linkage::Compute. Per-edge arrays are aligned with the CSR slots of
/// `Supervoxels::adjacency` (both directions of an edge carry the same value).
struct LinkageResult {
  /// 1 when the connection passes LCCP's convexity test (including the sanity criterion and,
  /// when enabled, extended convexity), per CSR slot.
  std::vector<uint8_t> edge_convex;
  /// 1 when the edge is kept (M+): convex and, with cut_on_type_change, same filtered type.
  std::vector<uint8_t> edge_kept;
  /// Patch type after the local-area-linkage majority filter, per supervoxel.
  std::vector<PatchType> filtered_type;
  /// Initial segment of each supervoxel, 0..num_segments-1. Segments are numbered in the
  /// order of their smallest supervoxel id.
  std::vector<int32_t> segment;
  /// Number of supervoxels in each segment.
  std::vector<uint32_t> segment_size;
  int num_segments{0};
  /// Wall time of the Compute that produced this result, milliseconds.
  double time_ms{0.0};
};

/// Local area linkage and LCCP convexity (docs/method.md section 3): decides for every
/// supervoxel adjacency whether it is kept, then takes connected components over kept edges
/// as initial segments and merges components smaller than `min_segment_supervoxels` into
/// their largest neighbouring segment.
///
/// Output is deterministic and independent of the pool size. Thread-safety: Compute is not
/// reentrant (reuses work buffers). Complexity: O(supervoxels + edges), plus O(edges * degree)
/// with extended convexity.
class Linkage {
 public:
  /// `pool` may be null (single-threaded) and must outlive the Linkage.
  /// @throws std::invalid_argument when `params` fail validation.
  explicit Linkage(const LinkageParams& params, core::ThreadPool* pool = nullptr);

  /// `features` must have one entry per supervoxel of `supervoxels` (centroids, normals and
  /// types are used).
  /// @throws std::runtime_error when sizes disagree or the adjacency is malformed.
  void Compute(const supervoxel::Supervoxels& supervoxels, const PatchFeatures& features,
               LinkageResult* result);

  const LinkageParams& params() const { return params_; }

 private:
  const LinkageParams params_;
  core::ThreadPool* const pool_;
  std::vector<uint32_t> reverse_slot_;
  std::vector<uint8_t> convex_raw_;
  std::vector<int32_t> parent_;
  std::vector<uint32_t> size_;
  std::vector<int32_t> new_id_;
  std::vector<uint32_t> member_start_;
  std::vector<uint32_t> members_;
  std::vector<uint32_t> fill_;
};

/// LCCP's convexity test for the connection of two patches with centroids `ci`, `cj`
/// (metres) and unit normals `ni`, `nj` oriented towards the camera. Symmetric in (i, j).
bool IsConvexConnection(const core::Vec3f& ci, const core::Vec3f& ni, const core::Vec3f& cj,
                        const core::Vec3f& nj, const LinkageParams& params);

}  // namespace clutterseg::graph
