#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/types.h"

namespace clutterseg::supervoxel {

/// Wall-clock time of each step of one Supervoxelizer::Compute, milliseconds.
struct SupervoxelTimings {
  double voxelize_ms{0.0};   ///< quantisation, key sort, per-voxel sums
  double adjacency_ms{0.0};  ///< 26-neighbourhood CSR
  double normals_ms{0.0};    ///< voxel normals and curvature
  double seeding_ms{0.0};    ///< seed cells, occupancy filter, move to low curvature
  double growth_ms{0.0};     ///< flow-constrained growth, refinement, connectivity, leftovers
  double output_ms{0.0};     ///< pixel labels, supervoxel statistics and adjacency
  double total_ms() const {
    return voxelize_ms + adjacency_ms + normals_ms + seeding_ms + growth_ms + output_ms;
  }
};

/// Output of the supervoxelizer for one frame (organized, or unorganized with height 1).
/// Supervoxels are numbered 0..N-1 in a deterministic order; all per-supervoxel arrays have N
/// entries. The adjacency is a symmetric CSR graph: the neighbours of i are
/// `adjacency[adjacency_offsets[i] .. adjacency_offsets[i + 1])`, sorted ascending, without self
/// loops.
struct Supervoxels {
  int width{0};
  int height{0};
  /// Per pixel (v * width + u): supervoxel id, or -1 for an invalid point.
  std::vector<int32_t> pixel_label;
  /// Mean of the member points, metres, camera frame.
  std::vector<core::Vec3f> centroid;
  /// Unit normal of the member points' best plane, oriented towards the camera.
  std::vector<core::Vec3f> normal;
  /// Surface variation l3 / (l1 + l2 + l3) of the member points' covariance.
  std::vector<float> curvature;
  /// Eigenvalues l1 >= l2 >= l3 of the member points' covariance, square metres (x = l1).
  std::vector<core::Vec3f> eigenvalues;
  /// Number of member points (pixels).
  std::vector<uint32_t> num_points;
  /// Raw moments of the member points, geometry::kNumMoments (10) per supervoxel: count, sums
  /// of x, y, z, sums of xx, xy, xz, yy, yz, zz (metres). Empty when the producer did not
  /// keep them; consumers then recompute them from the pixels.
  std::vector<double> moments;
  std::vector<uint32_t> adjacency_offsets;  ///< N + 1 entries
  std::vector<uint32_t> adjacency;          ///< 2 * edges entries
  /// Time of each step of the Compute that produced this output (zero when made elsewhere).
  SupervoxelTimings timings;
  /// The frame had more seeds than SupervoxelParams::max_supervoxels; some were left out.
  bool capped{false};

  size_t size() const { return centroid.size(); }
  size_t num_edges() const { return adjacency.size() / 2; }
};

}  // namespace clutterseg::supervoxel
