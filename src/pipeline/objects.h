#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/segmentation_result.h"

namespace clutterseg::pipeline {

/// Computes the per-object statistics (point count, centroid, axis-aligned and oriented
/// boxes, principal axes, mean colour, image bounding box, support plane) for the objects
/// of the label image over the `cloud` it labels. The support plane of an object is
/// the support plane nearest to its lowest axis-aligned-box corner, with the object on the
/// plane's camera side, or -1. The pixel passes run over bands of rows on `pool` when one
/// is given; the bands are fixed and summed in order, so the result does not depend on it.
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
  static void AccumulateRun(const core::Vec3f* xyz, const uint32_t* rgba, int u0, int u1, int v,
                            Accumulator* out);
  std::vector<Accumulator> acc_;
  std::vector<Frame> frames_;
  std::vector<Accumulator> band_acc_;  // per band of rows, then per object
  std::vector<Frame> band_frames_;
};

}  // namespace clutterseg::pipeline
