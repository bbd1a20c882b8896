#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/geometry/neighbor_index.h"
#include "clutterseg/geometry/voxel_grid.h"
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

/// What the border cues of LinkageParams (depth jumps, colour) read besides the supervoxels.
/// Each may be absent (null); a cue without its input is skipped.
struct LinkageCues {
  /// The cloud the supervoxels were made from (Supervoxels::pixel_label indexes its points):
  /// depths across the image border of an organized cloud, and colour.
  std::optional<core::PointCloudView> cloud;
  /// For an unorganized cloud: the voxels the supervoxels were grown over and the supervoxel
  /// of each voxel (supervoxel::Supervoxelizer::voxels() and voxel_label()). Border pairs are
  /// then voxels that are near neighbours in view direction.
  const geometry::VoxelGrid* voxels{nullptr};
  const std::vector<int32_t>* voxel_supervoxel{nullptr};
};

/// Local area linkage and LCCP convexity (docs/method.md section 3): decides for every
/// supervoxel adjacency whether it is kept, then takes connected components over kept edges
/// as initial segments and merges components smaller than `min_segment_supervoxels` into
/// their largest neighbouring segment. Before the components, optional cues cut edges the
/// convexity test keeps: crease evidence (graph only), depth jumps across the supervoxels'
/// border as seen from the camera, and colour (LinkageParams); after them the bridge cut
/// removes narrow bridges of kept edges between parts that meet along cut edges, and the
/// contact cut removes edges between parallel patches whose pixels do not touch.
///
/// Output is deterministic and independent of the pool size. Thread-safety: Compute is not
/// reentrant (reuses work buffers). Complexity: O(supervoxels + edges), plus O(edges * degree)
/// with extended convexity or crease evidence, plus O(pixels) for depth jumps on an organized
/// cloud (one pass over the label image in bands of rows on the pool, a second one for the
/// contact cut when it has candidates) or O(voxels log voxels) on an unorganized one (a k-d
/// tree over the voxels' view directions), plus O(points) for
/// colour, plus for the bridge cut at most bridge_max_edges + 2 breadth-first searches of a
/// component per crease edge inside it. Nothing is allocated once the buffers have grown to the
/// largest frame.
class Linkage {
 public:
  /// `pool` may be null (single-threaded) and must outlive the Linkage.
  /// @throws std::invalid_argument when `params` fail validation.
  explicit Linkage(const LinkageParams& params, core::ThreadPool* pool = nullptr);

  /// `features` must have one entry per supervoxel of `supervoxels` (centroids, normals and
  /// types are used).
  /// @throws std::runtime_error when sizes disagree or the adjacency is malformed.
  void Compute(const supervoxel::Supervoxels& supervoxels, const PatchFeatures& features,
               LinkageResult* result) {
    Compute(supervoxels, features, LinkageCues{}, result);
  }
  /// The same, with the inputs of the border cues.
  void Compute(const supervoxel::Supervoxels& supervoxels, const PatchFeatures& features,
               const LinkageCues& cues, LinkageResult* result);

  /// Computes the mean chromaticities of the supervoxels (a pass over the label image, when
  /// the colour cut is on and the cloud has colour) for the next Compute with the same
  /// `supervoxels` and `cues`, on the pool, while the pool has no other work (the Segmenter
  /// then runs Compute beside the plane labelling, which keeps a worker busy). Optional:
  /// Compute computes them itself when they were not prepared for its `supervoxels`. Call it
  /// on the thread of Compute, right before it.
  void PrepareCues(const supervoxel::Supervoxels& supervoxels, const LinkageCues& cues);

  const LinkageParams& params() const { return params_; }

 private:
  // Which cues the inputs allow. (The depth-jump counts need the convexity test's verdicts,
  // so they stay in Compute.)
  struct CueUse {
    bool image_jumps{false};  // depth jumps on the organized image
    bool view_jumps{false};   // depth jumps between voxels' view directions (unorganized)
    bool color{false};        // the colour cut and its wider concavity tolerance
    bool contact{false};      // the contact cut (organized image)
  };
  CueUse Use(const supervoxel::Supervoxels& sv, const LinkageCues& cues) const;

  // Depth-jump evidence per CSR slot of the lower supervoxel id (border_pairs_, jump_pairs_).
  void CountImageBorderPairs(const supervoxel::Supervoxels& sv, const core::PointCloudView& cloud);
  void CountViewBorderPairs(const supervoxel::Supervoxels& sv, const geometry::VoxelGrid& voxels,
                            const std::vector<int32_t>& voxel_supervoxel);
  // Contact cut (LinkageParams::contact_cut_max_pairs): adds the diagonal pixel pairs of the
  // candidate slots (contact_cut_, 1) to border_pairs_ and marks those still below the
  // limit (2).
  void CountDiagonalContacts(const supervoxel::Supervoxels& sv);
  // Clears out->edge_kept on the marked slots, then restores those whose two sides are not
  // both at least contact_cut_min_supervoxels.
  void CutContactless(const supervoxel::Supervoxels& sv, LinkageResult* out);
  // Bridge cut (LinkageParams::bridge_max_edges): clears out->edge_kept on narrow bridges
  // between parts of a component that meet along cut edges.
  void CutBridges(const supervoxel::Supervoxels& sv, const PatchFeatures& f, LinkageResult* out);
  // Share test of bridge_max_concave_share: `concave` of `kept` edges inside a side.
  bool ConcaveSide(uint32_t concave, uint32_t kept) const;
  // Mean chromaticity per supervoxel (mean_chroma_, 3 per supervoxel).
  void MeanChroma(const supervoxel::Supervoxels& sv, const core::PointCloudView& cloud);
  // The supervoxels PrepareCues last ran for, until the Compute that uses its cues.
  const supervoxel::Supervoxels* prepared_for_{nullptr};

  const LinkageParams params_;
  core::ThreadPool* const pool_;
  std::vector<uint32_t> reverse_slot_;
  std::vector<uint8_t> convex_raw_;
  std::vector<uint8_t> edge_class_;    // per slot: ConnectionClass of the convexity test
  std::vector<uint8_t> cue_cut_;       // per slot of the lower id: cut by a cue
  std::vector<uint8_t> contact_cut_;   // per slot of the lower id: 1 candidate, 2 to be cut
  std::vector<uint8_t> contact_node_;  // per supervoxel: has a candidate slot
  std::vector<uint32_t> border_pairs_;
  std::vector<uint32_t> jump_pairs_;
  std::vector<std::vector<uint32_t>> band_events_;  // per band: slot << 1 | jumped
  std::vector<std::vector<uint32_t>> band_pairs_;   // per band: border pixel pairs
  std::vector<uint32_t> column_begin_;  // first voxel of each column of the grid, and the end
  std::vector<float> view_dir_;         // 2 per voxel: x / z, y / z
  geometry::NeighborIndex view_index_;
  std::vector<std::vector<std::pair<uint32_t, float>>> chunk_found_;
  std::vector<float> mean_chroma_;
  std::vector<std::vector<uint32_t>> band_rgb_;  // per band: 4 per supervoxel (r, g, b, count)
  std::vector<std::vector<std::pair<uint32_t, float>>> chunk_best_;  // per chunk: (sv, |dz|)
  std::vector<int32_t> parent_;
  // Bridge cut: component of each supervoxel, BFS marks and parents, flow per slot.
  std::vector<int32_t> bridge_comp_;
  std::vector<uint32_t> bridge_mark_, bridge_from_slot_, bridge_from_node_;
  std::vector<uint32_t> bridge_queue_, bridge_touched_, bridge_cut_;
  std::vector<int8_t> bridge_flow_;
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
