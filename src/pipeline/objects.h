#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/pipeline/segmentation_result.h"

namespace clutterseg::pipeline {

/// Computes the per-object statistics (point count, centroid, axis-aligned and oriented
/// boxes, principal axes, mean colour, image bounding box, support plane) for the objects
/// 1..num_objects of `labels` over the organized `cloud`. The support plane of an object is
/// the support plane nearest to its lowest axis-aligned-box corner, with the object on the
/// plane's camera side, or -1. The pixel passes run over bands of rows on `pool` when one
/// is given; the bands are fixed and summed in order, so the result does not depend on it.
///
/// Thread-safety: Compute is not reentrant (it keeps work buffers, so steady-state frames do
/// not allocate); distinct instances are independent.
class ObjectExtractor {
 public:
  ObjectExtractor();
  ~ObjectExtractor();

  /// Fills `objects` (reusing its storage) with objects[k].id == k + 1.
  void Compute(const core::PointCloud& cloud, const core::LabelImage& labels, uint32_t num_objects,
               const std::vector<Plane>& planes, std::vector<Object>* objects,
               core::ThreadPool* pool = nullptr);

 private:
  struct Accumulator;
  struct Frame;
  std::vector<Accumulator> acc_;
  std::vector<Frame> frames_;
  std::vector<Accumulator> band_acc_;  // per band of rows, then per object
  std::vector<Frame> band_frames_;
};

}  // namespace clutterseg::pipeline
