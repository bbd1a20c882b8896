#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/core/types.h"

namespace clutterseg::geometry {

/// Parameters of the support-first step: large planes (table, floor, wall) found on the
/// pixel grid of an organized cloud before any voxel is made, in the manner of cell-based
/// plane detectors (CAPE): the image is cut into square cells, each cell's points give a
/// plane and its fit error, and neighbouring planar cells that agree grow into regions.
/// YAML section `segmenter.support`.
struct PlanarRegionParams {
  static constexpr std::string_view kSection = "segmenter.support";

  /// Run the step (organized clouds only; an unorganized cloud is left as it is). Off is
  /// the paper's pipeline: every point goes through the supervoxels.
  bool enabled{true};
  int cell_px{16};  ///< edge of a cell, pixels
  /// A cell takes part only when at least this share of its pixels is valid (cells along
  /// depth shadows and object silhouettes have holes).
  float min_valid_fraction{0.9f};
  /// A cell is planar when the RMS distance of its points to their fitted plane is at most
  /// this, metres, at 1 m depth; it scales with depth squared, like the sensor's depth noise
  /// and quantisation step.
  float max_rms_at_1m_m{0.002f};
  /// The RMS bound never goes below this, metres: the noise floor of the sensor near the
  /// camera (about 1.2 mm for a Kinect / Xtion; Nguyen, Izadi and Lovell 2012).
  float min_rms_m{0.0012f};
  /// A planar cell joins a neighbouring region when its normal lies within this angle of the
  /// region's plane, degrees (a single cell's normal is noisy far away)...
  float max_normal_angle_deg{15.0f};
  /// ...and the RMS distance of its points to that plane is at most this many times its RMS
  /// bound (the test of the merged fit: offset and tilt together).
  float max_region_rms{2.0f};
  /// A region at least the support area (objects.support_min_area_m2) takes the points of
  /// its blocks of half a cell that have no cell outside the region within this many pixels
  /// (cells outside the image do not count): a ring of the support of 8-16 px stays around
  /// each object for the supervoxels, so the plane labelling still sees the table next to
  /// its bottom. 0 = every cell of the region (lower WOv on mOSD and the synthetic rooms);
  /// 16 takes a quarter less of the table for no better quality (docs/results.md).
  int margin_px{8};
  /// Points of those cells farther from the plane than this many times the RMS bound at
  /// their depth stay in the cloud (a thin object lying on the table).
  float max_point_distance_rms{3.0f};

  /// @throws std::invalid_argument naming the key (`segmenter.support.<field>`) and value.
  void ValidateOrThrow() const;
};

/// One large plane found by PlanarRegionFinder: n . p + d = 0, n unit and towards the camera,
/// camera frame, metres.
struct PlanarRegion {
  core::Vec3f normal{0.f, 0.f, -1.f};
  float d{0.f};
  uint32_t num_cells{0};
  /// Metric area of all the region's cells, m^2 (at least the area the finder was given).
  float area_m2{0.f};
  /// Points taken from the cloud (set invalid) as this plane's, and their metric area, m^2.
  uint32_t num_taken_points{0};
  float taken_area_m2{0.f};
};

/// Output of PlanarRegionFinder::Compute.
struct PlanarRegions {
  std::vector<PlanarRegion> regions;  ///< largest first
  uint32_t num_taken_points{0};       ///< over all regions
  double time_ms{0.0};                ///< wall time of the Compute that produced it
};

/// Finds the large planes of an organized cloud on its pixel grid and takes their interior
/// points out of the cloud, so that the supervoxels (and every stage after them) work on the
/// objects and a margin of the support around them, not on the whole table, floor and wall.
/// The points within margin_px of a cell outside the region stay, so the plane hypotheses
/// still see the support next to each object and the objects' bottoms are cut from it as
/// before.
///
/// Cost: one pass over the points for the cell moments, one over the taken blocks, and a
/// region growing over the cells (1200 for 640x480 at 16 px). Thread-safety: Compute is not
/// reentrant (buffers are reused); distinct instances are independent. Work is split over
/// the pool given at construction by rows of cells: the output does not depend on its size.
class PlanarRegionFinder {
 public:
  /// `pool` may be null and must outlive the finder.
  /// @throws std::invalid_argument when `params` fail validation.
  explicit PlanarRegionFinder(const PlanarRegionParams& params, core::ThreadPool* pool = nullptr);

  /// Finds the regions of `cloud` (organized; metres, NaN = invalid) covering at least
  /// `min_area_m2` and sets the points they take to NaN. Leaves an unorganized cloud, or
  /// any cloud when the step is disabled, unchanged (no region).
  void Compute(const core::CameraIntrinsics& intrinsics, float min_area_m2, core::PointCloud* cloud,
               PlanarRegions* out);

  const PlanarRegionParams& params() const { return params_; }

 private:
  struct Cell {
    core::Vec3f centroid;
    core::Vec3f normal;
    float rms_bound{0.f};  // the RMS bound at the centroid's depth
    float flatness{0.f};   // RMS / bound; planar when <= 1
    bool planar{false};
  };

  const PlanarRegionParams params_;
  core::ThreadPool* const pool_;
  std::vector<double> moments_;   // kNumMoments per cell
  std::vector<uint32_t> pixels_;  // pixels per cell
  std::vector<Cell> cells_;
  std::vector<int32_t> cell_region_;
  std::vector<uint32_t> order_;
  std::vector<uint32_t> queue_;
  std::vector<uint32_t> taken_blocks_;  // cell * 4 + quadrant
  std::vector<uint32_t> block_taken_;   // per taken block: points taken, and their area
  std::vector<double> block_area_;
  std::vector<double> region_area_;  // per grown region, m^2
  struct RegionPlane {
    core::Vec3f normal;
    float d{0.f};
  };
  std::vector<double> region_moments_;  // kNumMoments per grown region
  std::vector<RegionPlane> region_plane_;
  std::vector<int32_t> region_root_;  // grown region -> the region it merged into
  std::vector<int32_t> region_out_;   // root -> index in the output, or -1
};

}  // namespace clutterseg::geometry
