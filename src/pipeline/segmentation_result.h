#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/types.h"
#include "clutterseg/pipeline/stage_times.h"

namespace clutterseg::pipeline {

/// A supporting plane n . p + d = 0 (n unit, towards the camera), camera frame, metres.
struct Plane {
  uint32_t id{0};
  core::Vec3f normal;
  float d{0.f};
  uint32_t num_points{0};
  float area_m2{0.f};      ///< metric area of the surface assigned to the plane
  bool is_support{false};  ///< table / floor / wall: its pixels are background (label 0)
};

/// One segmented object. All geometry in metres, camera frame.
struct Object {
  uint32_t id{0};  ///< the object's value in the label image (>= 1)
  uint32_t num_points{0};
  core::Vec3f centroid;
  core::Vec3f aabb_min;
  core::Vec3f aabb_max;
  core::Vec3f obb_center;
  core::Vec3f obb_axes[3];       ///< unit principal axes, largest variance first, right-handed
  core::Vec3f obb_extents;       ///< full side lengths along obb_axes
  int32_t support_plane_id{-1};  ///< id of the plane it stands on, -1 when none
  /// Gravity-aligned box, computed when the object has a support plane (otherwise false and
  /// every gbox_* and height field zero): gbox_axes[2] is the plane's normal pointing up (away
  /// from the plane, the object's side), gbox_axes[0] and [1] the sides of the minimum-area
  /// rectangle around the object's points projected onto the plane ([0] the longer side,
  /// right-handed); the box stands on the plane and reaches the object's highest point.
  bool has_gravity_box{false};
  core::Vec3f gbox_center;
  core::Vec3f gbox_axes[3];
  core::Vec3f gbox_extents;  ///< full side lengths along gbox_axes; [2] = height_m
  float height_m{0.f};       ///< highest point above the support plane, metres
  float bottom_m{0.f};       ///< lowest point above the support plane (< 0: below), metres
  core::Rgb8 mean_color;
  float confidence{1.f};                                                   ///< 0..1
  int32_t pixel_min_u{0}, pixel_min_v{0}, pixel_max_u{0}, pixel_max_v{0};  ///< image bbox
};

/// Everything the segmenter produces for one frame. Buffers are reused across frames.
struct SegmentationResult {
  int width{0};
  int height{0};
  core::LabelImage labels;      ///< 0 = background / invalid, k >= 1 = objects[k-1].id == k
  std::vector<Object> objects;  ///< ordered by id
  std::vector<Plane> planes;
  uint32_t num_supervoxels{0};
  uint32_t num_valid_points{0};
  /// Of those, the points the support-first step gave to a large plane before the supervoxels
  /// (segmenter.support): background, counted in their plane's num_points.
  uint32_t num_support_first_points{0};
  /// The frame reached a cap: more seeds than supervoxel.max_supervoxels (some left out), or
  /// more objects than objects.max_objects (the smallest became background).
  bool supervoxels_capped{false};
  bool objects_capped{false};
  StageTimes times;  ///< per stage (StageTable()) and the whole call
};

}  // namespace clutterseg::pipeline
