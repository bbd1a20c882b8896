#pragma once

#include <array>
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
  /// A region at least the support area (objects.support_min_area_m2) takes the points
  /// near its plane (see max_point_distance_rms) in its cells and in the cells around it,
  /// except those within this many pixels, in x and in y, of an object point (a valid point
  /// near no region's plane): a ring of the support of this width stays around each object
  /// for the supervoxels, so the plane labelling still sees the table next to its bottom.
  /// Missing pixels leave no ring. 0 = every point near the plane (lower WOv on mOSD and the
  /// synthetic rooms); 8, 12 and 16 measured no better (docs/method.md section 10).
  int margin_px{10};
  /// An island of kept points (8-connected object points and the support of their ring)
  /// with fewer object points than this gives its support points to the plane too: a lone
  /// point off the plane (a noise spike, far away) leaves no island that could pass for an
  /// object (0 = keep every ring; from 3 up mosd-learn loses 0.01, docs/method.md).
  int ring_min_cluster_px{2};
  /// A point is near a region's plane within this many times the RMS bound at its depth
  /// (farther: an object point, e.g. a thin object lying on the table).
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
  /// Metric area of all the region's cells, m^2 (at least the area the finder was given; the
  /// points taken may also come from the cells around the region).
  float area_m2{0.f};
  /// Points taken from the cloud (set invalid) as this plane's, and their metric area, m^2.
  uint32_t num_taken_points{0};
  float taken_area_m2{0.f};
};

/// Output of PlanarRegionFinder::Compute.
struct PlanarRegions {
  std::vector<PlanarRegion> regions;  ///< largest first
  uint32_t num_taken_points{0};       ///< over all regions
  /// The pixels taken, one bit each: row v's bits are the taken_words_per_row 64-bit words
  /// from v * taken_words_per_row, pixel u at bit u % 64 of word u / 64. Empty when nothing was
  /// taken (no region, an unorganized cloud, the step disabled).
  std::vector<uint64_t> taken_bits;
  size_t taken_words_per_row{0};
  /// Whether pixel (u, v) was taken; false outside the image or when nothing was.
  bool Taken(size_t u, size_t v) const {
    const size_t k = v * taken_words_per_row + u / 64;
    return u / 64 < taken_words_per_row && k < taken_bits.size() &&
           (taken_bits[k] >> (u % 64)) & 1u;
  }
  double time_ms{0.0};  ///< wall time of the Compute that produced it
};

/// Finds the large planes of an organized cloud on its pixel grid and takes their interior
/// points out of the cloud, so that the supervoxels (and every stage after them) work on the
/// objects and a margin of the support around them, not on the whole table, floor and wall.
/// The points within margin_px of an object point stay, so the plane hypotheses still see the
/// support next to each object and the objects' bottoms are cut from it as before.
///
/// Cost: one pass over the points for the cell moments, a region growing over the cells (1200
/// for 640x480 at 16 px), one pass over the points that tests them against their cells'
/// candidate planes (four at a time), a dilation of the object points' bit image and one pass
/// that takes the support points outside it. Thread-safety: Compute is not
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
  // Clears the ring bits of the kept islands (8-connected object points and the support
  // points of their ring) with fewer than `min_object_pixels` object points.
  void DropSmallIslands(size_t w, size_t h, uint32_t min_object_pixels);

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
  // Regions a cell's points may go to: its own, or for a cell outside every region the
  // regions nearest to it in 8-connected cell steps (ascending).
  struct CellCandidates {
    static constexpr uint8_t kMax = 4;
    std::array<int16_t, kMax> region{};
    std::array<float, kMax> pixel_area_m2{};  // metric area of a pixel on that plane, m^2
    uint8_t count{0};
  };
  std::vector<CellCandidates> cell_candidates_;
  std::vector<uint32_t> cell_step_;   // cell steps from the nearest region cell
  std::vector<uint8_t> region_core_;  // per output region: has a cell with all 8 neighbours in it
  // Per pixel of a cell with several candidates: the candidate + 1 of a support point.
  std::vector<uint8_t> pixel_candidate_;
  std::vector<uint64_t> object_bits_;   // per pixel row: bits of the object points
  std::vector<uint64_t> support_bits_;  // per pixel row: bits of the support points
  std::vector<uint64_t> row_bits_;      // object bits dilated along the rows
  std::vector<uint64_t> line_bits_;     // one row of bits per band of rows (scratch)
  std::vector<uint64_t> ring_bits_;     // within margin_px of an object point
  struct Run {
    uint32_t begin, end;  // pixels [begin, end) of a row
    uint32_t parent;      // union-find over runs
  };
  std::vector<Run> runs_;
  std::vector<uint32_t> run_row_start_;   // first run of each row, and the total
  std::vector<uint32_t> island_objects_;  // per root run: object points of its island
  std::vector<uint64_t> kept_bits_;       // object points and the support points of the ring
  std::vector<uint32_t> band_taken_;      // per band of rows and region: points taken, area
  std::vector<double> band_area_;
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
