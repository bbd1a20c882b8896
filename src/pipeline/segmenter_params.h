#pragma once

#include <string_view>

#include "clutterseg/graph/linkage_params.h"
#include "clutterseg/optimize/plane_params.h"
#include "clutterseg/pipeline/working_cloud.h"
#include "clutterseg/supervoxel/supervoxel_params.h"

namespace clutterseg::pipeline {

/// Refinement and object extraction (docs/method.md section 6). YAML section
/// `segmenter.objects`.
struct ObjectParams {
  static constexpr std::string_view kSection = "segmenter.objects";

  int min_object_points{150};  ///< smaller segments are dropped (label 0)
  /// A plane whose assigned surface covers at least this area is a support (table, floor,
  /// wall) and becomes background, m^2. Object faces are smaller.
  float support_min_area_m2{0.15f};
  /// Object points closer than this to a support plane become background, metres (0 = off).
  float support_snap_distance_m{0.0f};
  /// Segments whose centroid lies this far below a support plane (table edges and legs,
  /// things under the table) are background, metres (0 = keep them).
  float below_support_margin_m{0.005f};

  /// @throws std::invalid_argument naming the key (`segmenter.objects.<field>`) and value.
  void ValidateOrThrow() const;
};

/// All parameters of one Segmenter, one struct per stage in stage order. Defaults are the
/// measured best configuration; see docs/configuration.md for every key and
/// docs/method.md for the paper's settings (config/paper.yaml).
struct SegmenterParams {
  PointsParams points;
  supervoxel::SupervoxelParams supervoxel;
  graph::LinkageParams linkage;
  optimize::PlaneParams planes;
  ObjectParams objects;

  /// Validates every section once. @throws std::invalid_argument naming the key and value.
  void ValidateOrThrow() const;
};

}  // namespace clutterseg::pipeline
