#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/segmentation_result.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::pipeline {

/// The neck cut (docs/method.md section 7, ObjectParams::neck_cut_max_width_m): two objects
/// that touch at a point or along a short contact (two cans side by side whose tops meet, a
/// bottle lying against a box's edge) can be joined by the few supervoxels at the contact,
/// and then form one object whose outline in the image narrows to a neck there. Each object
/// of an organized cloud is eroded by a disc of half the neck width (in pixels at its mean
/// depth); when that leaves two or more cores that each hold neck_cut_min_share of its pixels,
/// every pixel goes to the core it reaches first within the object (4-connected, breadth
/// first), and the parts holding min_object_points or more become objects of their own, the
/// largest keeping the object's label. Two tests keep one surface seen around an occluder
/// whole:
/// - occlusion: of the valid pixels outside the object within a neck width of the cut line,
///   no more than neck_cut_max_occluded_share lie 1 cm or more in front of the line (an
///   occluder in front narrows the outline of what it hides, not of what stands apart);
/// - one plane: the cut is left when every part is planar (RMS at most 5 mm) and one plane
///   through all of them fits within 1.5 times the worst part's RMS plus 1 mm (a book seen
///   around a box standing on it).
///
/// Unorganized clouds are left as they are (no image outline). Objects keep ids in the order
/// of their first pixel.
///
/// Thread-safety: Compute is not reentrant (reuses work buffers); distinct instances are
/// independent. The objects are searched in parallel on the pool, in at most 16 chunks with
/// buffers of their own; the result does not depend on it.
class NeckCutter {
 public:
  /// `pool` may be null (single-threaded) and must outlive the cutter.
  explicit NeckCutter(const ObjectParams& params, core::ThreadPool* pool = nullptr);

  /// Splits the objects of result->labels (1..result->objects.size()) over `cloud` (same
  /// layout, organized) at their necks, relabels them in first-pixel order and resizes
  /// result->objects (default entries; ObjectExtractor fills them). `intrinsics` are the
  /// cloud's (their focal length turns the neck width into pixels). Adds its time to
  /// result->times[Stage::kRefine]. Returns the number of objects cut. Allocates nothing once
  /// its buffers have grown.
  uint32_t Compute(const core::PointCloudView& cloud, const core::CameraIntrinsics& intrinsics,
                   SegmentationResult* result);

 private:
  // An object's pixel box, pixel count and the sum of the depths of its sampled pixels.
  struct Box {
    int x0, y0, x1, y1;  // inclusive
    uint32_t count, z_count;
    double z_sum;
  };
  // The buffers of one object's search; a chunk of objects searched one after the other
  // shares one. The partition's arrays cover the object's box and a ring of one pixel around
  // it (outside the object), `w` x `h` from image pixel (x0, y0).
  struct Work {
    int x0, y0, w, h;
    std::vector<uint16_t> dist;    // chamfer distances (3 per pixel step), 0 outside
    std::vector<int32_t> owner;    // core of each pixel, -1 none
    std::vector<uint32_t> size;    // pixels per core (then per part)
    std::vector<uint32_t> queue;   // flood fill and breadth-first order
    std::vector<uint8_t> is_part;  // per core: big enough to be a part
    std::vector<uint32_t> line;    // the cut line's pixels (image indices)
    std::vector<float> depths;     // their depths
    std::vector<uint16_t> flank;   // chamfer distances to the line around it
  };
  // Partitions object k (label k + 1) into the cores of its erosion by `radius` pixels and
  // gives each of its pixels to one (work->owner); returns the number of parts (cores big
  // enough and holding min_object_points once every pixel has gone to one).
  int Partition(const core::PointCloudView& cloud, uint32_t k, int radius, Work* work) const;
  // Whether object k is cut (the partition and both tests).
  bool Search(const core::PointCloudView& cloud, float fx, uint32_t k, Work* work) const;
  // The pixel radius of the erosion for object k.
  int Radius(float fx, uint32_t k) const;

  const ObjectParams params_;
  core::ThreadPool* const pool_;
  const uint32_t* labels_{nullptr};  // the labels of the current Compute
  std::vector<Box> boxes_;
  std::vector<uint8_t> cut_;
  std::vector<Work> work_;
  std::vector<uint32_t> relabel_;
};

}  // namespace clutterseg::pipeline
