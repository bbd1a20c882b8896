#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "clutterseg/graph/patch_features.h"
#include "clutterseg/optimize/alpha_expansion.h"
#include "clutterseg/optimize/plane_params.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::optimize {

/// A plane n . p + d = 0 in the camera frame (metres); `normal` is unit and points towards
/// the camera, so d > 0 for a plane that does not pass behind the camera centre.
struct PlaneModel {
  core::Vec3f normal{0.f, 0.f, -1.f};
  float d{0.f};
  uint32_t num_points{0};   ///< member points of the supervoxels assigned to the plane
  uint32_t num_patches{0};  ///< supervoxels assigned to the plane
  /// A plane given to PlaneLabeler::Compute before the supervoxels (found on the pixel grid):
  /// the points it took from the cloud (not in any supervoxel) and their metric area, m^2.
  /// Zero for the planes found here.
  uint32_t fixed_points{0};
  float fixed_area_m2{0.f};
};

/// Output of PlaneLabeler::Compute.
struct PlaneLabeling {
  /// Planes that received at least one supervoxel or hold fixed points (see Compute): the
  /// unmatched fixed planes first, then the found ones in order of acceptance.
  std::vector<PlaneModel> planes;
  /// Per supervoxel: index into `planes`, or -1 for l0 ("on no plane").
  std::vector<int32_t> patch_plane;
  /// Hypotheses accepted before labelling (some may end with no supervoxel).
  int num_hypotheses{0};
  double energy{0.0};  ///< final energy, in units of rho (see PlaneParams)
  int expansion_cycles{0};
  /// Wall times of the Compute that produced this labelling, milliseconds: the
  /// alpha-expansion, and everything else (hypotheses, unary costs, renumbering).
  double hypotheses_ms{0.0};
  double expansion_ms{0.0};
};

/// Plane hypotheses from planar low-curvature patches, total-least-squares refit on the
/// inlier patches' points, and the assignment of every supervoxel to a plane or to l0 by
/// alpha-expansion on the energy of docs/method.md section 5 (units in PlaneParams).
///
/// Deterministic. Thread-safety: Compute is not reentrant (reuses buffers). Complexity:
/// O(max_candidate_trials * N) for the hypotheses plus the expansion moves.
class PlaneLabeler {
 public:
  /// @throws std::invalid_argument when `params` fail validation.
  explicit PlaneLabeler(const PlaneParams& params);

  /// Finds planes from `features` and labels every supervoxel of `supervoxels` (adjacency
  /// for the smoothness term). `features` must have one entry per supervoxel.
  /// @throws std::runtime_error when the sizes disagree.
  void Compute(const supervoxel::Supervoxels& supervoxels, const graph::PatchFeatures& features,
               PlaneLabeling* out);
  /// The same with `fixed` planes found before the supervoxels (fixed_points > 0). A found
  /// plane along a fixed one (within duplicate_angle_deg and duplicate_distance_m) takes its
  /// fixed_points and fixed_area_m2 and keeps its own fit unless the normals differ by more
  /// than fixed_fit_max_angle_deg (then the fixed plane's fit); a fixed plane no found plane
  /// matches is a hypothesis ahead of the found ones. Planes holding fixed points stay in the
  /// output even with no supervoxel.
  void Compute(const supervoxel::Supervoxels& supervoxels, const graph::PatchFeatures& features,
               const std::vector<PlaneModel>& fixed, PlaneLabeling* out);

  /// Plane hypotheses only: candidates grown and refitted from the flattest uncovered seed
  /// patches (at most max_candidate_trials), then accepted largest first (by inlier points)
  /// unless they duplicate an accepted plane, up to max_planes; num_points / num_patches
  /// count the inliers of the final refit.
  void FindPlanes(const graph::PatchFeatures& features, std::vector<PlaneModel>* planes);

  const PlaneParams& params() const { return params_; }

 private:
  // Patches with at least min_patch_points points, packed for the inlier scans.
  struct PackedPatch {
    core::Vec3f centroid;
    core::Vec3f normal;
    uint32_t index;
  };
  void Label(const supervoxel::Supervoxels& supervoxels, const graph::PatchFeatures& features,
             const std::vector<PlaneModel>& fixed, PlaneLabeling* out);
  void PackPatches(const graph::PatchFeatures& f);
  // Patches within rho (times tolerance_scale) of the plane whose normal is within the inlier
  // angle (times tolerance_scale, capped below 90 deg) and, with a centre, within radius_m of it.
  void CollectInliers(const core::Vec3f& normal, float d, float tolerance_scale,
                      const core::Vec3f* center, float radius_m, std::vector<uint32_t>* inliers);

  const PlaneParams params_;
  AlphaExpansion expansion_;
  struct Candidate {
    PlaneModel model;
    core::Vec3f inlier_centroid;  // point-weighted mean of the inlier patch centroids
    uint32_t order{0};            // position in seed order (tie-break)
  };
  std::vector<Candidate> candidates_;
  std::vector<PlaneModel> hypotheses_;
  std::vector<PlaneModel> found_;
  std::vector<uint32_t> seeds_;
  std::vector<uint32_t> inliers_;
  std::vector<PackedPatch> packed_;
  // The same patches as planes of floats (centroid x, y, z, normal x, y, z), padded to a
  // multiple of four with zero normals, which no inlier test passes.
  std::vector<float> soa_[6];
  std::vector<std::pair<float, uint32_t>> by_x_;  // (centroid x, packed position), ascending
  std::vector<uint32_t> near_;                    // scratch of neighbourhood queries
  std::vector<uint8_t> covered_;
  std::vector<float> unary_;
  std::vector<int32_t> labels_;
  std::vector<int32_t> remap_;
};

namespace internal {

/// Total-least-squares plane through the union of the member points of `patches`, computed
/// exactly from their counts, centroids and covariances. Returns false when the patches hold
/// fewer than 3 points. The normal is oriented towards the camera.
bool FitPlane(const graph::PatchFeatures& f, const std::vector<uint32_t>& patches,
              core::Vec3f* normal, float* d, uint32_t* num_points);

}  // namespace internal

}  // namespace clutterseg::optimize
