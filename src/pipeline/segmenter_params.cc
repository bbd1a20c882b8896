#include "clutterseg/pipeline/segmenter_params.h"

#include "clutterseg/core/param_check.h"

namespace clutterseg::pipeline {

void ObjectParams::ValidateOrThrow() const {
  const core::ParamCheck check(kSection);
  check.InRange("min_object_points", min_object_points, 1, 100000000);
  check.InRange("max_objects", max_objects, 1, 65535);
  check.InRange("support_min_area_m2", support_min_area_m2, 1e-6f, 1e4f, "m^2");
  check.InRange("support_snap_distance_m", support_snap_distance_m, 0.f, 1.f, "m");
  check.InRange("below_support_margin_m", below_support_margin_m, 0.f, 10.f, "m");
  check.InRange("plane_merge_max_pair_angle_deg", plane_merge_max_pair_angle_deg, 0.f, 180.f,
                "deg");
  check.InRange("above_support_distance_m", above_support_distance_m, 1e-6f, 1.f, "m");
  check.InRange("support_release_fraction", support_release_fraction, 0.f, 1.f);
  check.InRange("support_release_min_height_m", support_release_min_height_m, 0.f, 10.f, "m");
  check.InRange("support_release_enclosed_max_area_m2", support_release_enclosed_max_area_m2, 0.f,
                1e4f, "m^2");
  check.InRange("support_reclaim_passes", support_reclaim_passes, 0, 1000);
  check.InRange("support_reclaim_max_step_rel", support_reclaim_max_step_rel, 0.f, 10.f);
  check.InRange("container_max_axis_offset_rel", container_max_axis_offset_rel, 0.f, 10.f);
  check.InRange("vessel_rim_cut_margin_rel", vessel_rim_cut_margin_rel, 0.f, 10.f);
  check.InRange("vessel_fit_tolerance_rel", vessel_fit_tolerance_rel, 0.01f, 1.f);
  check.InRange("vessel_min_inlier_share", vessel_min_inlier_share, 0.f, 1.f);
  check.InRange("container_min_radius_m", container_min_radius_m, 0.f, 10.f, "m");
  check.InRange("container_max_radius_m", container_max_radius_m, container_min_radius_m, 10.f,
                "m");
  check.InRange("container_max_radius_diff_rel", container_max_radius_diff_rel, 0.f, 10.f);
  check.InRange("container_max_fit_rms_rel", container_max_fit_rms_rel, 0.f, 100.f);
  check.InRange("stack_cut_min_step_m", stack_cut_min_step_m, 0.f, 1.f, "m");
  check.InRange("stack_cut_max_step_m", stack_cut_max_step_m, stack_cut_min_step_m, 1.f, "m");
  check.InRange("stack_cut_min_significance", stack_cut_min_significance, 0.f, 1e6f);
  check.InRange("stack_cut_face_angle_deg", stack_cut_face_angle_deg, 1.f, 45.f, "deg");
  check.InRange("stack_cut_min_face_width_m", stack_cut_min_face_width_m, 0.f, 10.f, "m");
  check.InRange("stack_cut_max_face_noise_m", stack_cut_max_face_noise_m, 1e-5f, 1.f, "m");
  check.InRange("stack_cut_max_face_sag_m", stack_cut_max_face_sag_m, 0.f, 1.f, "m");
  check.InRange("neck_cut_max_width_m", neck_cut_max_width_m, 0.f, 1.f, "m");
  check.InRange("neck_cut_min_share", neck_cut_min_share, 0.01f, 0.5f);
  check.InRange("neck_cut_max_occluded_share", neck_cut_max_occluded_share, 0.f, 1.f);
}

void SegmenterParams::ValidateOrThrow() const {
  temporal.ValidateOrThrow();
  partition.ValidateOrThrow();
  points.ValidateOrThrow();
  support.ValidateOrThrow();
  supervoxel.ValidateOrThrow();
  linkage.ValidateOrThrow();
  planes.ValidateOrThrow();
  objects.ValidateOrThrow();
}

}  // namespace clutterseg::pipeline
