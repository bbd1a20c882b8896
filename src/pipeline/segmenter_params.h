#pragma once

#include <string_view>

#include "clutterseg/geometry/planar_regions.h"
#include "clutterseg/graph/linkage_params.h"
#include "clutterseg/optimize/plane_params.h"
#include "clutterseg/pipeline/partition_prior.h"
#include "clutterseg/pipeline/temporal_filter.h"
#include "clutterseg/pipeline/working_cloud.h"
#include "clutterseg/supervoxel/supervoxel_params.h"

namespace clutterseg::pipeline {

/// Refinement and object extraction (docs/method.md section 6). YAML section
/// `segmenter.objects`.
struct ObjectParams {
  static constexpr std::string_view kSection = "segmenter.objects";

  int min_object_points{150};  ///< smaller segments are dropped (label 0)
  /// At most this many objects per frame: beyond it the largest are kept (ids still in the
  /// order of their first pixel) and the rest become background; SegmentationResult::
  /// objects_capped says so. Keeps objects_t within what a subscriber receives and ids
  /// within the label image's 16 bits.
  int max_objects{1000};
  /// A plane whose assigned surface covers at least this area is a support (table, floor,
  /// wall) and becomes background, m^2. Object faces are smaller.
  float support_min_area_m2{0.15f};
  /// Object points closer than this to a support plane become background, metres (0 = off).
  float support_snap_distance_m{0.0f};
  /// Segments whose centroid lies this far below a support plane (table edges and legs,
  /// things under the table) are background, metres (0 = keep them).
  float below_support_margin_m{0.005f};
  /// Pieces of one non-support plane that touch merge only when their two patch normals lie
  /// within this angle of each other, degrees (180 = whenever both are planar, the paper's
  /// rule). Alpha-expansion gives a small face next to a box's top the top's plane; without
  /// the check, that face's box and the next one become one object (docs/method.md).
  float plane_merge_max_pair_angle_deg{60.0f};
  /// A point more than this above its support plane (signed distance along the plane's
  /// normal) counts as above the support for the release and reclaim below, metres.
  float above_support_distance_m{0.004f};
  /// A support-plane supervoxel with at least this share of its points above the support is
  /// released: it is foreground and grouped like the others (0 = off). Catches the lowest
  /// part of an object that alpha-expansion put on the table's plane.
  float support_release_fraction{0.5f};
  /// A group made only of released supervoxels stays an object only when its points stand
  /// this high above the support on average, metres; otherwise it is background again (table
  /// pieces slightly off the fitted plane). 0 = every such group stays.
  float support_release_min_height_m{0.008f};
  /// Such a group stays an object whatever its height when its piece of the support (the
  /// support supervoxels and released-only groups connected to it) covers at most this area,
  /// m^2 (measured as support_min_area_m2), and touches an object: the bottom inside a pot or a
  /// bowl, a few millimetres above the table and walled in by the vessel (0 = off). With
  /// container_max_axis_offset_rel it joins the object group it shares the most adjacencies
  /// with.
  float support_release_enclosed_max_area_m2{0.04f};
  /// A group none of whose supervoxels has its centroid more than above_support_distance_m
  /// above one support plane lies flat on it (or below it): a piece of the table that the
  /// plane labelling gave another plane or none (on a real table, one slightly off the fitted
  /// plane), the table's front edge seen from above. It is
  /// background like a low group of released supervoxels, and kept (or joined to the vessel
  /// around it) under the same enclosure rule. false = such pieces are objects (the paper).
  bool support_flat_groups{true};
  /// Points of the remaining support supervoxels that lie above the support take the label of
  /// an adjacent object point, spreading up to this many neighbours into the support (0 =
  /// off): the object side of supervoxels straddling an object's bottom and the table. No
  /// label spreads across a depth step larger than support_reclaim_max_step_rel times the
  /// depth. Neighbours are the 4 pixels of an organized cloud, the 8 nearest points of an
  /// unorganized one.
  int support_reclaim_passes{8};
  float support_reclaim_max_step_rel{0.02f};  ///< dimensionless; see support_reclaim_passes
  /// A group smaller than min_object_points joins the adjacent foreground group it shares the
  /// most supervoxel adjacencies with (ties: the larger group) instead of being dropped; an
  /// isolated small group is still dropped.
  bool merge_small_groups{true};
  /// Container insides join their outside (0 = off). Each group's patches are fitted with the
  /// centre c and radius r that best satisfy c = p + r n over its patch centroids p and
  /// normals n (normals towards the camera): r > 0 for a surface seen from its concave side
  /// (the inside of a cup or bowl), r < 0 for a convex one. A concave group joins the convex
  /// group whose centre lies within this share of the larger radius of its own, measured
  /// across the largest support plane's normal (the two walls of one vessel share its axis),
  /// when both radii lie within [container_min_radius_m, container_max_radius_m], differ by
  /// at most container_max_radius_diff_rel of the larger, and the centres lie within two
  /// radii of each other along the normal. Up is the normal of the support plane nearest the
  /// inside on the camera's side; without one nothing joins. The rim between the two walls is
  /// thin and seen edge-on, so their supervoxels are often not adjacent at all, and mOSD's
  /// part labels count the inside as a part of its own (docs/method.md section 7).
  float container_max_axis_offset_rel{0.0f};
  /// Vessel insides end at their rim (0 = off). Seen from above, the far inside wall of a cup
  /// or bowl continues smoothly into the surface of whatever touches the vessel behind its
  /// rim (another vessel's outside, a can, a box's face), with no concave crease to cut. Each
  /// group standing over a support is searched for the inside of a vessel: a vertical axis c
  /// and radius r (container_min_radius_m..container_max_radius_m) with c = p + r n, across
  /// the support's normal, for at least vessel_min_inlier_share of its wall patches' points
  /// (patches whose normals lie mostly across the normal; from every pair of wall patches, the
  /// pair whose circle the most walls fit within vessel_fit_tolerance_rel of r), refitted by
  /// least squares on those walls, which must face the axis from around it. The supervoxels
  /// of the group farther from the axis than r (1 + this), at least 1 cm more, are cut off
  /// and become groups of their own (with the supervoxels of the same surface adjacent to
  /// them that do not fit the circle); the fitting walls never are. Nothing changes for a
  /// vessel that touches nothing (docs/method.md section 7).
  float vessel_rim_cut_margin_rel{0.2f};
  /// A wall patch fits the circle when c - p - r n is at most this share of r (at least
  /// 6 mm); see vessel_rim_cut_margin_rel.
  float vessel_fit_tolerance_rel{0.2f};
  /// Share of a group's wall-patch points that must fit one circle; see
  /// vessel_rim_cut_margin_rel.
  float vessel_min_inlier_share{0.4f};
  /// Radii of vessels, metres; see container_max_axis_offset_rel and
  /// vessel_rim_cut_margin_rel.
  float container_min_radius_m{0.01f};
  float container_max_radius_m{0.2f};         ///< metres; see container_min_radius_m
  float container_max_radius_diff_rel{0.5f};  ///< dimensionless; see container_max_axis_offset_rel
  /// A group is fitted only when its RMS residual across the normal is at most this share of
  /// its radius (a body of revolution about a vertical axis); see
  /// container_max_axis_offset_rel.
  float container_max_fit_rms_rel{1.0f};
  /// Flush stacks are cut (0 = off): an object whose upright face steps, along its height, by
  /// at least this much between two planar parts (the front of a box stacked on another,
  /// standing a few millimetres in front of or behind the lower front) is split there, its
  /// part above the step an object of its own, metres (StackCutter, docs/method.md section 7).
  float stack_cut_min_step_m{0.004f};
  /// Larger steps are not a flush stack (the two parts meet at a crease the linkage cuts, or
  /// the surface is curved), metres; see stack_cut_min_step_m.
  float stack_cut_max_step_m{0.010f};
  /// The step must be at least this many standard errors of the difference of the two parts'
  /// offsets (robust noise of the points, their counts); see stack_cut_min_step_m.
  float stack_cut_min_significance{20.0f};
  /// A face is the upright points whose normals lie within this angle of its direction
  /// across the support's normal, degrees; see stack_cut_min_step_m.
  float stack_cut_face_angle_deg{8.0f};
  /// Each part of the face spans at least this width across it (5..95 % of its points),
  /// metres; see stack_cut_min_step_m.
  float stack_cut_min_face_width_m{0.04f};
  /// Each part's robust noise (1.4826 MAD of its offsets) is at most this, metres; see
  /// stack_cut_min_step_m.
  float stack_cut_max_face_noise_m{0.003f};
  /// The face bends across its width by at most this (the sagitta of a parabola through its
  /// offsets over its 5..95 % width: a cylinder's side is not a face), metres; see
  /// stack_cut_min_step_m.
  float stack_cut_max_face_sag_m{0.002f};
  /// Objects are cut at necks of their outline in the image narrower than this (0 = off): two
  /// objects joined only where they touch at a point or along a short contact (cans side by
  /// side whose tops meet), metres at the object's mean depth (NeckCutter, docs/method.md
  /// section 7). Organized clouds only.
  float neck_cut_max_width_m{0.016f};
  /// Each side of a neck holds at least this share of the object's pixels (past the neck, and
  /// min_object_points once cut); see neck_cut_max_width_m.
  float neck_cut_min_share{0.2f};
  /// A neck is left when more than this share of the valid pixels beside its cut line (within a
  /// neck width, outside the object) lie 1 cm or more in front of it: an occluder narrows what
  /// it hides; see neck_cut_max_width_m.
  float neck_cut_max_occluded_share{0.3f};

  /// @throws std::invalid_argument naming the key (`segmenter.objects.<field>`) and value.
  void ValidateOrThrow() const;
};

/// All parameters of one Segmenter, one struct per stage in stage order. Defaults are the
/// measured best configuration; see docs/configuration.md for every key and
/// docs/method.md for the paper's settings (config/paper.yaml).
struct SegmenterParams {
  /// The temporal depth filter of a stream, applied before the Segmenter by the program that
  /// owns the stream (the daemon), in frame order; the Segmenter itself does not read it.
  TemporalFilterParams temporal;
  /// The hysteresis on the partition of a stream, applied after the Segmenter by the program
  /// that owns the stream, in frame order; the Segmenter itself does not read it.
  PartitionPriorParams partition;
  PointsParams points;
  geometry::PlanarRegionParams support;
  supervoxel::SupervoxelParams supervoxel;
  graph::LinkageParams linkage;
  optimize::PlaneParams planes;
  ObjectParams objects;

  /// Validates every section once. @throws std::invalid_argument naming the key and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::pipeline
