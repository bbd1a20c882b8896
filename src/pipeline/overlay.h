#pragma once

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"

namespace clutterseg::pipeline {

/// A distinct, stable display colour for object id `id` (>= 1); id 0 gives black.
core::Rgb8 LabelColor(uint32_t id);

/// An image of the cloud for display: its colour when it has one, otherwise the depth
/// shaded grey (near = bright); invalid points black. Reuses `out`'s storage.
void CloudToImage(const core::PointCloud& cloud, core::ColorImage* out);

/// An image of a depth image (millimetres, 0 = invalid) for display when a frame has no
/// colour: shaded grey, near = bright, invalid pixels black. Reuses `out`'s storage.
void DepthToImage(const core::DepthImage& depth, core::ColorImage* out);

/// Draws `labels` over `base` (same size; may be null for a black base): each object's
/// pixels are blended with its LabelColor, object borders drawn solid, background dimmed.
/// Reuses `out`'s storage.
void RenderOverlay(const core::LabelImage& labels, const core::ColorImage* base,
                   core::ColorImage* out);

}  // namespace clutterseg::pipeline
