#pragma once

#include <array>
#include <cstdint>
#include <tuple>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/geometry/neighbor_index.h"
#include "clutterseg/geometry/planar_regions.h"
#include "clutterseg/graph/linkage.h"
#include "clutterseg/graph/patch_features.h"
#include "clutterseg/optimize/planes.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/segmenter_params.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::pipeline {

/// Refinement (docs/method.md section 6): support planes become background, except support
/// supervoxels that stand mostly above their plane (released; a group of released ones alone
/// must stand clearly above it, and a group lying flat on a support plane is support too,
/// unless walled in by an object like the bottom inside a pot); the remaining supervoxels are
/// grouped into objects by the initial segments (restricted to foreground and re-split where
/// removing the background disconnected them) and by pieces of one non-support plane that touch
/// with similar normals; groups smaller than min_object_points join their most connected neighbour
/// (or are dropped); points of support supervoxels above the support next to an object take its
/// label (reclaim). Object ids are assigned in the order of each object's first point (row-
/// major in an organized cloud), so output is deterministic.
///
/// Organized and unorganized clouds take the same steps; where an organized cloud's pixel grid
/// is used (the support area per pixel, the reclaim's 4-neighbours), an unorganized cloud uses
/// the patches' spread (area) and the nearest points (geometry::NeighborIndex).
///
/// Thread-safety: Compute is not reentrant (reuses work buffers); distinct instances are
/// independent.
class Refiner {
 public:
  /// `pool` may be null (single-threaded) and must outlive the Refiner.
  /// @throws std::invalid_argument when `params` fail validation.
  explicit Refiner(const ObjectParams& params, core::ThreadPool* pool = nullptr);

  /// Writes result->labels (already sized to the frame), result->planes, num_objects
  /// default entries in result->objects (labels 1..num_objects; ObjectExtractor fills their
  /// statistics) and its time in result->times[Stage::kRefine]. `intrinsics` are read only
  /// for an organized `cloud`. The passes over the points (two, in bands) and the reclaim's
  /// neighbour search run on the pool; the result does not depend on it. Nothing is allocated
  /// once the buffers have grown to the largest frame. `support_first` (may be null) is the
  /// frame's support-first step, whose taken pixels (the interior of the large planes, no
  /// longer in `cloud`) tell a piece of the support next to them from one walled in by an
  /// object (support_release_enclosed_max_area_m2).
  void Compute(const core::CameraIntrinsics& intrinsics, const core::PointCloud& cloud,
               const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features,
               const graph::LinkageResult& link, const optimize::PlaneLabeling& planes,
               SegmentationResult* result, const geometry::PlanarRegions* support_first = nullptr);

 private:
  // A plane n . x + d = 0 as four floats.
  struct PlaneEq {
    float nx{0.f}, ny{0.f}, nz{0.f}, d{0.f};
  };
  // Per band of points.
  struct Band {
    std::vector<std::pair<uint32_t, uint32_t>> first;  // (supervoxel, its first point)
    std::vector<uint8_t> seen;
    std::vector<uint32_t> above;  // points above the support, per supervoxel
    std::vector<uint32_t> candidates;
    std::vector<uint32_t> anchors;
  };

  int32_t Find(int32_t x);
  bool KeepGroup(const optimize::PlaneLabeling& planes, int32_t g) const;
  // Keeps the `cap` largest labelled groups (group_label_), the others become background;
  // returns the number kept.
  uint32_t KeepLargestGroups(uint32_t cap);
  void Union(int32_t a, int32_t b);
  void SumGroups(const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features);
  void MergeSmallGroups(const supervoxel::Supervoxels& sv);
  // Cuts off what lies beyond a vessel's rim (objects.vessel_rim_cut_margin_rel).
  void CutVesselRims(const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features,
                     const optimize::PlaneLabeling& planes);
  // touches_taken_[s] = 1 for the supervoxels with a pixel next to a pixel support_first took.
  void MarkTouchingTaken(const supervoxel::Supervoxels& sv,
                         const geometry::PlanarRegions& support_first);
  // group_flat_[g] = 1 for the groups lying flat on a support plane (support_flat_groups).
  void MarkFlatGroups(const supervoxel::Supervoxels& sv, const optimize::PlaneLabeling& planes);
  // The support plane nearest below the point sum * inv (on its camera side), -1 for none.
  int32_t SupportBelow(const optimize::PlaneLabeling& planes, const core::Vec3f& sum,
                       double inv) const;
  // Joins the concave groups (container insides) to the convex group around the same axis
  // (ObjectParams::container_max_axis_offset_rel).
  void MergeContainerInsides(const supervoxel::Supervoxels& sv,
                             const graph::PatchFeatures& features,
                             const optimize::PlaneLabeling& planes);
  void ReclaimOrganized(const core::PointCloud& cloud, core::LabelImage* labels);
  void ReclaimUnorganized(const core::PointCloud& cloud, core::LabelImage* labels);

  const ObjectParams params_;
  core::ThreadPool* const pool_;
  std::vector<int32_t> parent_;
  std::vector<uint8_t> background_;
  std::vector<uint8_t> released_;
  std::vector<uint8_t> support_;
  std::vector<double> plane_area_;
  std::vector<PlaneEq> support_plane_;  // [s + 1]
  std::vector<Band> bands_;
  std::vector<uint32_t> sv_first_;
  std::vector<uint32_t> above_count_;
  std::vector<uint8_t> group_unreleased_;
  std::vector<int32_t> group_encloser_;
  std::vector<uint8_t> group_flat_;        // per group root: it lies flat on a support
  std::vector<float> flat_height_;         // per group root: its highest centroid over a plane, m
  std::vector<int32_t> low_root_;          // per supervoxel: its group when that is low, else -1
  std::vector<int32_t> component_;         // piece of the support of each supervoxel
  std::vector<double> component_area_;     // per piece, m^2
  std::vector<uint8_t> component_open_;    // per piece: next to the large planes' taken pixels
  std::vector<uint8_t> touches_taken_;     // per supervoxel: next to a taken pixel
  static constexpr uint8_t kSkip = 2;      // touches_taken_: not a piece of the support
  std::vector<double> sv_area_;            // per supervoxel on a plane, m^2 (as plane_area_)
  std::vector<int32_t> component_object_;  // per piece: the one object group it touches
  std::vector<uint32_t> stack_;
  std::vector<double> group_height_;
  std::vector<uint64_t> group_height_points_;
  std::vector<uint64_t> group_points_;
  std::vector<std::tuple<uint64_t, uint32_t, size_t>> capped_order_;  // points, label, group
  std::vector<core::Vec3f> group_centroid_;
  std::vector<uint64_t> pair_keys_;
  std::vector<std::pair<int32_t, int32_t>> merge_into_;
  // The sums of MergeContainerInsides per group root, and the fit made from them.
  struct FitSums {
    double w{0.0};
    double n[3]{}, p[3]{};
    double nn[3][3]{}, pp[3][3]{}, np[3][3]{};  // w n n^T, w p p^T, w n p^T
  };
  struct ContainerFit {
    std::array<double, 3> center{};  // on the axis, projected across the support's normal
    double radius{0.0};              // > 0 concave (an inside), < 0 convex
    double height{0.0};              // mean of the points along the support's normal
    int32_t support{-1};
  };
  std::vector<FitSums> group_fit_sums_;
  std::vector<ContainerFit> group_fit_;
  std::vector<int32_t> container_roots_;
  // CutVesselRims: a wall patch of a group across the support's normal (position x, y, unit
  // normal nx, ny), its points and its supervoxel.
  struct VesselWall {
    double x, y, nx, ny, w;
    uint32_t member;
  };
  std::vector<uint32_t> rim_members_;  // supervoxels ordered by group
  std::vector<uint32_t> rim_offsets_;  // group g's members: [rim_offsets_[g], [g + 1])
  std::vector<uint32_t> rim_fill_;
  std::vector<int32_t> rim_root_;       // per supervoxel, its group before the cut
  std::vector<uint8_t> rim_cut_;        // per supervoxel: kRimFits, kRimCut or 0
  std::vector<uint8_t> rim_cut_group_;  // per group root: it was cut
  std::vector<VesselWall> rim_walls_;
  std::vector<uint32_t> group_first_;
  std::vector<std::pair<uint32_t, size_t>> group_order_;
  std::vector<uint32_t> group_label_;
  std::vector<uint32_t> sv_label_;     // [s + 1]: object label of supervoxel s, 0 = none
  std::vector<uint8_t> reclaim_from_;  // [s + 1]
  std::vector<uint8_t> anchor_;        // [s + 1]
  std::vector<uint32_t> candidates_;
  std::vector<uint32_t> anchors_;
  std::vector<std::pair<uint32_t, uint32_t>> takes_;
  std::vector<float> reclaim_xyz_;
  std::vector<uint32_t> neighbors_;
  std::vector<uint32_t> reclaim_label_;
  geometry::NeighborIndex reclaim_index_;
};

}  // namespace clutterseg::pipeline
