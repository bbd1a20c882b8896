#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/segmentation_result.h"

namespace clutterseg::pipeline {

/// Computes the per-object statistics (point count, centroid, axis-aligned and oriented
/// boxes, principal axes, mean colour, image bounding box, support plane, gravity-aligned box)
/// for the objects of the label image over the `cloud` it labels, in the cloud's (camera)
/// frame. The support plane of an object is the support plane nearest to its lowest point
/// (within 0.1 m), with its centroid on the plane's camera side, or -1.
///
/// Gravity-aligned box of an object with a support plane: its points are projected onto the
/// plane and the box's footprint is the minimum-area rectangle around them (rotating an edge
/// of their convex hull: exact for the hull, and a box seen from a corner, whose visible
/// faces project to an L, still gets its own edges, where principal axes in the plane would
/// take the L's diagonal). The hull is taken over the extreme points of 512 columns of the
/// projection, so the rectangle may fall short of a point by at most 1/512 of the object's
/// width along the first plane axis. Its height is the highest point above the plane.
///
/// The pixel passes run over bands of rows on `pool` when one is given; the bands are fixed
/// and summed in order, so the result does not depend on it. The support planes and gravity
/// boxes run on it one object per task.
///
/// Thread-safety: Compute is not reentrant (it keeps work buffers, so steady-state frames do
/// not allocate); distinct instances are independent.
class ObjectExtractor {
 public:
  /// `pool` may be null (single-threaded) and must outlive the extractor.
  explicit ObjectExtractor(core::ThreadPool* pool = nullptr);
  ~ObjectExtractor();
  ObjectExtractor(const ObjectExtractor&) = delete;
  ObjectExtractor& operator=(const ObjectExtractor&) = delete;

  /// Fills the statistics of the result->objects.size() objects of result->labels
  /// (objects[k].id == k + 1) over `cloud` (same layout as the label image), with
  /// result->planes for the support planes, and its time in result->times[Stage::kObjects].
  void Compute(const core::PointCloudView& cloud, SegmentationResult* result);

 private:
  core::ThreadPool* const pool_;
  struct Accumulator;
  struct Frame;
  struct BoxWork;
  // The support plane of objects[k] and its gravity-aligned box, from points_ (`work`: that
  // object's buffers; distinct objects may run at once).
  void SupportAndGravityBox(const std::vector<Plane>& planes, uint32_t k, BoxWork* work,
                            Object* o) const;
  static void AccumulateRun(const core::Vec3f* xyz, const uint32_t* rgba, int u0, int u1, int v,
                            Accumulator* out);
  std::vector<Accumulator> acc_;
  std::vector<Frame> frames_;
  std::vector<Accumulator> band_acc_;  // per band of rows, then per object
  std::vector<Frame> band_frames_;
  // Each object's valid points (per object, per band in band order), where each band's part
  // of an object goes next (per band, then per object), where each object's points start.
  std::vector<core::Vec3f> points_;
  std::vector<size_t> point_start_;
  std::vector<size_t> object_first_;
  // The gravity boxes' work buffers, one set per object (the boxes run on the pool).
  std::vector<BoxWork> box_work_;
};

}  // namespace clutterseg::pipeline
