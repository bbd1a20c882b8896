#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/segmenter_params.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::pipeline {

/// The flush-stack cut (docs/method.md section 7, ObjectParams::stack_cut_min_step_m): an
/// object stacked on another with their fronts nearly flush leaves no crease between the two
/// fronts for the linkage to cut, but the upper front stands a few millimetres in front of or
/// behind the lower one. For each object over a support plane (the nearest support plane below
/// its centroid), the points of its supervoxels whose normals lie within 17.5 degrees of the
/// plane, upright faces, are grouped by the direction their supervoxel faces (up to three
/// faces, each the points within stack_cut_face_angle_deg of the most common direction left).
/// Along each face's height a split is tried every 2 mm: the 8 mm bands right beside it must
/// step (medians) by at least 0.7 of the step between the two sides' medians, which must lie
/// within stack_cut_min_step_m..stack_cut_max_step_m and be at least
/// stack_cut_min_significance standard errors (robust noise, point counts); each side has at
/// least min_object_points points, spans 1 cm of height and stack_cut_min_face_width_m across,
/// and is planar (robust noise at most stack_cut_max_face_noise_m, no bend across the face
/// beyond stack_cut_max_face_sag_m: a cylinder's side is not a face). A first look at the mean
/// offsets in 2 mm bins of height leaves only the splits whose bands step by half the smallest
/// step for that test. The object's points more than 3 mm above the most significant split of
/// all its faces become an object of their own when both parts keep min_object_points.
///
/// Organized and unorganized clouds alike (the normals are the supervoxels'). Objects keep ids
/// in the order of their first point.
///
/// Thread-safety: Compute is not reentrant (reuses work buffers); distinct instances are
/// independent. The objects are searched in parallel on the pool, in at most 16 chunks with
/// buffers of their own; the result does not depend on it.
class StackCutter {
 public:
  /// `pool` may be null (single-threaded) and must outlive the cutter.
  explicit StackCutter(const ObjectParams& params, core::ThreadPool* pool = nullptr);

  /// Splits the objects of result->labels (1..result->objects.size()) over `cloud` (same
  /// layout) that show a flush stack, relabels them in first-point order and resizes
  /// result->objects (default entries; ObjectExtractor fills them). `sv` are the frame's
  /// supervoxels (their pixel_label in the same layout, their normals); result->planes gives
  /// the support planes. Adds its time to result->times[Stage::kRefine]. Returns the number
  /// of cuts. Allocates nothing once its buffers have grown.
  uint32_t Compute(const core::PointCloudView& cloud, const supervoxel::Supervoxels& sv,
                   SegmentationResult* result);

 private:
  // An upright supervoxel of the object: the unit direction it faces across the support's
  // normal, its azimuth bin, its points in the object, the face it went to (0: none yet).
  struct Entry {
    float x, y, z;
    int bin;
    uint32_t points;
    uint8_t face;
  };
  // The buffers of one object's search; a chunk of objects searched one after the other
  // shares one.
  struct Work {
    std::vector<int32_t> sv_entry;  // per supervoxel: its entry, -1 unseen, -2 not upright
    std::vector<Entry> entries;
    std::vector<int32_t> touched;              // the supervoxels whose sv_entry was set
    std::vector<uint32_t> up_pixel, up_entry;  // upright points: pixel, entry
    std::vector<int> hist;                     // azimuths, one bin per degree
    std::vector<uint32_t> face;                // the current face's pixels
    std::vector<float> h, r, e;   // their height, offset along its normal, position across
    std::vector<double> bin_sum;  // per bin of the scan step: sum of offsets, count
    std::vector<uint32_t> bin_count;
    std::vector<float> candidates;  // heights of the splits the bins let through
    std::vector<uint32_t> order;    // face points by height
    std::vector<float> hs, rs, es;  // h, r, e in that order
    std::vector<float> a, b, tmp;   // medians and percentiles
  };
  // The split of an object: its points higher than `height` (plus a 3 mm margin) above the
  // support plane n . p + d = 0 (towards the camera) are cut off; NaN for none.
  struct Cut {
    float height;
    float nx, ny, nz, d;
    bool Above(const core::Vec3f& p) const;
  };
  Cut Search(const core::PointCloudView& cloud, const supervoxel::Supervoxels& sv,
             const std::vector<Plane>& planes, uint32_t k, Work* work) const;

  const ObjectParams params_;
  core::ThreadPool* const pool_;
  std::vector<uint32_t> offsets_;  // object k's pixels: pixels_[offsets_[k], offsets_[k + 1])
  std::vector<uint32_t> pixels_;
  std::vector<uint32_t> fill_;
  std::vector<Work> work_;
  std::vector<Cut> cuts_;
  std::vector<uint32_t> relabel_;
};

}  // namespace clutterseg::pipeline
