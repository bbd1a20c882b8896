#pragma once

#include <string_view>

namespace clutterseg::graph {

/// Parameters of local area linkage and convexity (docs/method.md sections 2-3).
struct LinkageParams {
  static constexpr std::string_view kSection = "segmenter.linkage";

  /// Below this normal angle a concave edge still counts as convex, degrees (LCCP and the
  /// paper: 10; 35 measured best, docs/method.md).
  float concavity_tolerance_deg{35.0f};
  bool use_sanity_criterion{true};     ///< LCCP's sanity check on the connection direction
  bool use_extended_convexity{false};  ///< an edge is convex only if common neighbours agree
  /// With extended convexity: a convex edge stays convex only when at least this many common
  /// neighbours form convex triangles with it (LCCP's k; edges without common neighbours are
  /// then cut).
  int extended_convexity_k{1};
  bool use_type_filter{true};  ///< the LAL majority filter on patch types
  /// Cut edges whose (filtered) patch types differ (the paper: true; false measured best).
  bool cut_on_type_change{false};
  float convexity_epsilon{0.0f};   ///< slack on (n_i - n_j) . d > 0, dimensionless
  int min_segment_supervoxels{1};  ///< smaller components merge into a neighbour
  /// The sanity criterion judges only connections whose normals differ by at least this,
  /// degrees (0 = every connection, as LCCP). Below 20 degrees its threshold is under 9
  /// degrees and mostly cuts flat, noisy connections inside objects (docs/method.md).
  float sanity_min_angle_deg{20.0f};

  /// Depth-jump cut: an otherwise kept edge is cut when at least depth_jump_min_pairs point
  /// pairs lie across the two supervoxels' border as seen from the camera and at least
  /// depth_jump_fraction of them differ in depth by more than depth_jump_rel times the nearer
  /// depth (dimensionless; 0 = off). Border pairs are 4-neighbour pixels of an organized cloud,
  /// and voxels that are nearest neighbours in view direction in an unorganized one
  /// (docs/method.md). Separates objects that touch at one end and stand one behind the other.
  float depth_jump_rel{0.02f};
  float depth_jump_fraction{0.5f};  ///< share of border pairs that must jump, 0..1
  int depth_jump_min_pairs{3};      ///< fewer border pairs are no evidence

  /// Crease evidence: a concave connection kept only by the concavity tolerance, with a
  /// normal angle of at least this (degrees), is cut when a common neighbour of its two
  /// patches has a concave connection sharper than the tolerance to either of them: a mild
  /// stretch of a crease between two objects (0 = off).
  float crease_min_angle_deg{0.0f};

  /// Colour cut (clouds with colour only): a concave connection whose normal angle is at
  /// least color_min_angle_deg is cut when the patches' mean chromaticities (255 r / (r + g +
  /// b), and g, b alike) differ by more than this Euclidean distance (0 = off).
  float color_threshold{10.0f};
  float color_min_angle_deg{35.0f};  ///< degrees; see color_threshold
  /// With the colour cut on and a cloud with colour, the concavity tolerance is this instead
  /// of concavity_tolerance_deg, degrees: concave connections between the two are kept only
  /// between patches of one colour (the colour cut from color_min_angle_deg), which joins the
  /// curved insides of cups and bowls. Without colour the cut cannot tell them from the
  /// contacts between objects, and concavity_tolerance_deg holds (0 = always). Off by
  /// default: on frames it was not chosen on it also joins touching objects of one colour
  /// (docs/method.md section 7); 60 is the value it was measured with.
  float color_concavity_tolerance_deg{0.0f};

  /// Bridge cut (docs/method.md section 7): two parts of one component of kept edges that
  /// meet along a crease the linkage cuts, and are held together only by a narrow bridge of
  /// kept edges elsewhere (a can on a box whose front is flush with the box's, a book against
  /// a tin joined where their faces continue each other), are cut at the bridge. For every edge
  /// (i, j) inside one component that the convexity test cuts as concave beyond the tolerance,
  /// the fewest kept edges that separate i from j are found
  /// (unit-capacity max-flow over the kept edges); the cut is made when there are at most this
  /// many (0 = off), ...
  int bridge_max_edges{2};
  /// ...the cut edges between the two sides (creases and cue cuts) number at least this many
  /// times the bridge's edges (dimensionless)...
  float bridge_min_crease_ratio{3.0f};
  /// ...each side has at least this many supervoxels (the other side of a piece of rim is
  /// the rest of its own object)...
  int bridge_min_supervoxels{8};
  /// ...every bridge edge joins patches whose normals differ by at most this, degrees (a
  /// sharp convex edge, such as a rim, is evidence of one object)...
  float bridge_max_angle_deg{45.0f};
  /// ...and on neither side are more than this share of the kept edges concave (a concave
  /// surface is the inside of a vessel, whose crease with its own outside is no contact).
  float bridge_max_concave_share{0.6f};

  /// Contact cut (organized clouds only; docs/method.md section 7): two patches that are
  /// neighbours in space but whose pixels do not touch in the image are not seen to touch,
  /// such as the inside bottom of a cup and the book under it, next to each other across the
  /// cup's thin wall (the wall lies between them in the image). An edge the other tests keep
  /// is cut when the two patches' pixels meet in fewer than this many pairs of 8-neighbour
  /// pixels (0 = off)...
  int contact_cut_max_pairs{1};
  /// ...and their normals differ by at most this, degrees (two faces parallel across a wall:
  /// the cut leaves creases and curved surfaces to the convexity test)...
  float contact_cut_max_angle_deg{25.84f};
  /// ...and, after all cuts, both sides it separates have at least this many supervoxels (a
  /// patch of an object seen only past a thin gap in its own surface stays with it).
  int contact_cut_min_supervoxels{4};

  /// @throws std::invalid_argument naming the key (`segmenter.linkage.<field>`) and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::graph
