#include "clutterseg/config/segmenter_keys.h"

namespace clutterseg::config {

// The one place that maps YAML keys under `segmenter:` to pipeline::SegmenterParams fields.
// Key path = "<section>.<field>"; the type (bool, int, float, ...) comes from the field.
#define CLUTTERSEG_SEGMENTER_KEY(section, field)                    \
  MakeKey(#section "." #field, &pipeline::SegmenterParams::section, \
          &decltype(pipeline::SegmenterParams::section)::field)
// The voxel grid's fields, written in the supervoxel section.
#define CLUTTERSEG_GRID_KEY(field)          \
  MakeAccessKey<pipeline::SegmenterParams>( \
      "supervoxel." #field, [](auto& p) -> auto& { return p.supervoxel.grid.field; })

const std::vector<Key<pipeline::SegmenterParams>>& SegmenterKeys() {
  static const std::vector<Key<pipeline::SegmenterParams>> kKeys = {
      CLUTTERSEG_SEGMENTER_KEY(temporal, enabled),
      CLUTTERSEG_SEGMENTER_KEY(temporal, max_frames),
      CLUTTERSEG_SEGMENTER_KEY(temporal, band_at_1m_m),
      CLUTTERSEG_SEGMENTER_KEY(temporal, min_band_m),
      CLUTTERSEG_SEGMENTER_KEY(temporal, hole_fill_frames),

      CLUTTERSEG_SEGMENTER_KEY(partition, hold_frames),
      CLUTTERSEG_SEGMENTER_KEY(partition, min_still_share),
      CLUTTERSEG_SEGMENTER_KEY(partition, min_cover_share),
      CLUTTERSEG_SEGMENTER_KEY(partition, cut_piece_joins_rest),
      CLUTTERSEG_SEGMENTER_KEY(partition, min_pixels),
      CLUTTERSEG_SEGMENTER_KEY(partition, arrival_gap_frames),
      CLUTTERSEG_SEGMENTER_KEY(partition, arrival_confirm_frames),
      CLUTTERSEG_SEGMENTER_KEY(partition, arrival_min_share),
      CLUTTERSEG_SEGMENTER_KEY(partition, arrival_moved_min_pixels),
      CLUTTERSEG_SEGMENTER_KEY(partition, arrival_rejoin_min_contact),
      CLUTTERSEG_SEGMENTER_KEY(partition, arrival_join_min_contact),

      CLUTTERSEG_SEGMENTER_KEY(points, min_depth_m),
      CLUTTERSEG_SEGMENTER_KEY(points, max_depth_m),

      CLUTTERSEG_SEGMENTER_KEY(support, enabled),
      CLUTTERSEG_SEGMENTER_KEY(support, cell_px),
      CLUTTERSEG_SEGMENTER_KEY(support, min_valid_fraction),
      CLUTTERSEG_SEGMENTER_KEY(support, max_rms_at_1m_m),
      CLUTTERSEG_SEGMENTER_KEY(support, min_rms_m),
      CLUTTERSEG_SEGMENTER_KEY(support, max_normal_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(support, max_region_rms),
      CLUTTERSEG_SEGMENTER_KEY(support, margin_px),
      CLUTTERSEG_SEGMENTER_KEY(support, ring_min_cluster_px),
      CLUTTERSEG_SEGMENTER_KEY(support, max_point_distance_rms),

      CLUTTERSEG_GRID_KEY(voxel_resolution_m),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, seed_resolution_m),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, color_importance),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, spatial_importance),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, normal_importance),
      CLUTTERSEG_GRID_KEY(use_single_camera_transform),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, refinement_iterations),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, growth_regions),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, min_seed_occupancy),
      CLUTTERSEG_SEGMENTER_KEY(supervoxel, max_supervoxels),

      CLUTTERSEG_SEGMENTER_KEY(linkage, concavity_tolerance_deg),
      CLUTTERSEG_SEGMENTER_KEY(linkage, use_sanity_criterion),
      CLUTTERSEG_SEGMENTER_KEY(linkage, use_extended_convexity),
      CLUTTERSEG_SEGMENTER_KEY(linkage, extended_convexity_k),
      CLUTTERSEG_SEGMENTER_KEY(linkage, use_type_filter),
      CLUTTERSEG_SEGMENTER_KEY(linkage, cut_on_type_change),
      CLUTTERSEG_SEGMENTER_KEY(linkage, convexity_epsilon),
      CLUTTERSEG_SEGMENTER_KEY(linkage, min_segment_supervoxels),
      CLUTTERSEG_SEGMENTER_KEY(linkage, sanity_min_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(linkage, depth_jump_rel),
      CLUTTERSEG_SEGMENTER_KEY(linkage, depth_jump_fraction),
      CLUTTERSEG_SEGMENTER_KEY(linkage, depth_jump_min_pairs),
      CLUTTERSEG_SEGMENTER_KEY(linkage, crease_min_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(linkage, color_threshold),
      CLUTTERSEG_SEGMENTER_KEY(linkage, color_min_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(linkage, color_concavity_tolerance_deg),
      CLUTTERSEG_SEGMENTER_KEY(linkage, bridge_max_edges),
      CLUTTERSEG_SEGMENTER_KEY(linkage, bridge_min_crease_ratio),
      CLUTTERSEG_SEGMENTER_KEY(linkage, bridge_min_supervoxels),
      CLUTTERSEG_SEGMENTER_KEY(linkage, bridge_max_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(linkage, bridge_max_concave_share),
      CLUTTERSEG_SEGMENTER_KEY(linkage, contact_cut_max_pairs),
      CLUTTERSEG_SEGMENTER_KEY(linkage, contact_cut_max_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(linkage, contact_cut_min_supervoxels),

      CLUTTERSEG_SEGMENTER_KEY(planes, inlier_distance_m),
      CLUTTERSEG_SEGMENTER_KEY(planes, inlier_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(planes, min_inlier_patches),
      CLUTTERSEG_SEGMENTER_KEY(planes, max_seed_curvature),
      CLUTTERSEG_SEGMENTER_KEY(planes, max_planes),
      CLUTTERSEG_SEGMENTER_KEY(planes, duplicate_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(planes, duplicate_distance_m),
      CLUTTERSEG_SEGMENTER_KEY(planes, fixed_fit_max_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(planes, smoothness_weight),
      CLUTTERSEG_SEGMENTER_KEY(planes, feature_weight),
      CLUTTERSEG_SEGMENTER_KEY(planes, no_plane_cost_factor),
      CLUTTERSEG_SEGMENTER_KEY(planes, max_expansion_cycles),
      CLUTTERSEG_SEGMENTER_KEY(planes, normal_mismatch_cost),
      CLUTTERSEG_SEGMENTER_KEY(planes, max_candidate_trials),
      CLUTTERSEG_SEGMENTER_KEY(planes, seed_neighborhood_m),
      CLUTTERSEG_SEGMENTER_KEY(planes, accept_largest_first),
      CLUTTERSEG_SEGMENTER_KEY(planes, min_patch_points),
      CLUTTERSEG_SEGMENTER_KEY(planes, refit_iterations),

      CLUTTERSEG_SEGMENTER_KEY(objects, min_object_points),
      CLUTTERSEG_SEGMENTER_KEY(objects, max_objects),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_min_area_m2),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_snap_distance_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, below_support_margin_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, plane_merge_max_pair_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(objects, above_support_distance_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_release_fraction),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_release_min_height_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_release_enclosed_max_area_m2),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_flat_groups),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_reclaim_passes),
      CLUTTERSEG_SEGMENTER_KEY(objects, support_reclaim_max_step_rel),
      CLUTTERSEG_SEGMENTER_KEY(objects, merge_small_groups),
      CLUTTERSEG_SEGMENTER_KEY(objects, container_max_axis_offset_rel),
      CLUTTERSEG_SEGMENTER_KEY(objects, vessel_rim_cut_margin_rel),
      CLUTTERSEG_SEGMENTER_KEY(objects, vessel_fit_tolerance_rel),
      CLUTTERSEG_SEGMENTER_KEY(objects, vessel_min_inlier_share),
      CLUTTERSEG_SEGMENTER_KEY(objects, container_min_radius_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, container_max_radius_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, container_max_radius_diff_rel),
      CLUTTERSEG_SEGMENTER_KEY(objects, container_max_fit_rms_rel),
      CLUTTERSEG_SEGMENTER_KEY(objects, stack_cut_min_step_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, stack_cut_max_step_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, stack_cut_min_significance),
      CLUTTERSEG_SEGMENTER_KEY(objects, stack_cut_face_angle_deg),
      CLUTTERSEG_SEGMENTER_KEY(objects, stack_cut_min_face_width_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, stack_cut_max_face_noise_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, stack_cut_max_face_sag_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, neck_cut_max_width_m),
      CLUTTERSEG_SEGMENTER_KEY(objects, neck_cut_min_share),
      CLUTTERSEG_SEGMENTER_KEY(objects, neck_cut_max_occluded_share),
  };
  return kKeys;
}

#undef CLUTTERSEG_GRID_KEY
#undef CLUTTERSEG_SEGMENTER_KEY

const KeyTable<pipeline::SegmenterParams>& SegmenterKeyTable() {
  static const KeyTable<pipeline::SegmenterParams> kTable = [] {
    std::vector<Key<pipeline::SegmenterParams>> keys;
    for (const auto& k : SegmenterKeys()) keys.push_back({"segmenter." + k.path, k.set, k.get});
    return KeyTable<pipeline::SegmenterParams>(std::move(keys));
  }();
  return kTable;
}

void LoadSegmenterParams(const std::string& path, pipeline::SegmenterParams* params) {
  SegmenterKeyTable().LoadYaml(path, params, "segmenter");
}

void ApplySegmenterOverride(const std::string& assignment, pipeline::SegmenterParams* params) {
  SegmenterKeyTable().ApplyOverride(
      assignment.rfind("segmenter.", 0) == 0 ? assignment : "segmenter." + assignment, params);
}

}  // namespace clutterseg::config
