#pragma once

#include <cstdint>
#include <vector>

#include "core/point_cloud.h"
#include "pipeline/segmentation_result.h"

namespace clutterseg::pipeline {

/// Computes the per-object statistics (point count, centroid, axis-aligned and oriented
/// boxes, principal axes, mean colour, image bounding box, support plane) for the objects
/// 1..num_objects of `labels` over the organized `cloud`. The support plane of an object is
/// the support plane nearest below its lowest points (the one whose signed distance to the
/// object's points is smallest and positive), or -1.
/// Reuses `objects`' storage. Thread-safety: pure function.
void ComputeObjects(const core::PointCloud& cloud, const core::LabelImage& labels,
                    uint32_t num_objects, const std::vector<Plane>& planes,
                    std::vector<Object>* objects);

}  // namespace clutterseg::pipeline
