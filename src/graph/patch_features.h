#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"
#include "clutterseg/geometry/moments.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::graph {

/// Geometric type of a surface patch (docs/method.md section 2).
enum class PatchType : uint8_t {
  kNonPlanar = 0,
  kPlanar = 1,
};

/// Per-supervoxel geometric features, as parallel flat arrays indexed by supervoxel id. All
/// geometry is in the camera frame (metres, x right, y down, z forward).
struct PatchFeatures {
  /// Number of member points (valid pixels carrying the supervoxel's id).
  std::vector<uint32_t> num_points;
  /// Mean of the member points, metres.
  std::vector<core::Vec3f> centroid;
  /// Population covariance of the member points about the centroid, m^2, stored as
  /// (xx, xy, xz, yy, yz, zz).
  std::vector<std::array<float, 6>> covariance;
  /// Eigenvalues of the covariance (l1 >= l2 >= l3 >= 0), m^2, stored as (x=l1, y=l2, z=l3).
  std::vector<core::Vec3f> eigenvalues;
  /// Unit eigenvector of l3, oriented towards the camera (normal . centroid <= 0).
  std::vector<core::Vec3f> normal;
  /// Surface variation l3 / (l1 + l2 + l3), in [0, 1/3].
  std::vector<float> curvature;
  /// Dimensionality features with s_k = sqrt(l_k): a1D = (s1 - s2) / s1 (linear),
  /// a2D = (s2 - s3) / s1 (planar), a3D = s3 / s1 (scattered); they sum to 1 (all 0 for
  /// degenerate patches).
  std::vector<float> a1d;
  std::vector<float> a2d;
  std::vector<float> a3d;
  /// kPlanar when a2D > a1D and a2D > a3D; patches with fewer than 3 points are kNonPlanar.
  std::vector<PatchType> type;
  /// Wall time of the Compute that produced these features, milliseconds.
  double time_ms{0.0};

  size_t size() const { return centroid.size(); }
  /// Resizes every array to `n` entries (reusing capacity).
  void Resize(size_t n);
};

/// Computes PatchFeatures from the member points of each supervoxel.
///
/// When the supervoxelizer kept its members' moments (the normal case) the features follow
/// from them without a pass over the pixels: only the covariance is formed, the eigenpairs
/// and normals are the supervoxelizer's (geometry::SummarizeMoments). Otherwise points are
/// accumulated (in double precision) per fixed block of image rows, the block sums combined
/// in block order, and each patch summarised by geometry::SummarizeMoments; either way the
/// output is bit-identical for any thread count.
///
/// Thread-safety: Compute is not reentrant (it reuses work buffers); distinct instances are
/// independent. Complexity: O(pixels + supervoxels).
class PatchFeatureExtractor {
 public:
  /// `pool` may be null (single-threaded) and must outlive the extractor.
  explicit PatchFeatureExtractor(core::ThreadPool* pool = nullptr) : pool_(pool) {}

  /// Fills `features` with one entry per supervoxel of `supervoxels`, reading the points of
  /// `cloud` (organized, same width and height as `supervoxels`). Pixels with label -1 or an
  /// invalid (non-finite) point are ignored. features->time_ms is this call's wall time.
  /// @throws std::runtime_error when the sizes disagree or a pixel label is out of range.
  void Compute(const core::PointCloud& cloud, const supervoxel::Supervoxels& supervoxels,
               PatchFeatures* features);

 private:
  core::ThreadPool* const pool_;
  std::vector<double> block_sums_;  // blocks x supervoxels x kMoments
  std::vector<uint8_t> bad_block_;
};

namespace internal {

/// Fills the feature entries of patch `i` of `features` from raw moments: point count `n`,
/// coordinate sums `sum` (x, y, z) and sums of products `sum_sq` (xx, xy, xz, yy, yz, zz).
void FinishPatch(double n, const double sum[3], const double sum_sq[6], size_t i,
                 PatchFeatures* features);
/// Fills the feature entries of patch `i` (`n` > 0 points) from its shape summary.
void FinishPatchShape(double n, const geometry::ShapeSummary& shape, size_t i,
                      PatchFeatures* features);

}  // namespace internal

}  // namespace clutterseg::graph
