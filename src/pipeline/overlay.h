#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"
#include "clutterseg/pipeline/segmentation_result.h"

namespace clutterseg::pipeline {

/// A distinct, stable display colour for object id `id` (>= 1); id 0 gives black.
core::Rgb8 LabelColor(uint32_t id);

/// An image of the cloud for display: its colour when it has one, otherwise the depth
/// shaded grey (near = bright); invalid points black. Reuses `out`'s storage.
void CloudToImage(const core::PointCloud& cloud, core::ColorImage* out);

/// A picture of an unorganized cloud and its labels (one per point) as the camera with
/// `intrinsics` would see them, for display only: each valid point projected to pixel
/// (round(fx x / z + cx), round(fy y / z + cy)), the nearest point winning a pixel; pixels no
/// point reaches are invalid. `view` gets the points (and colour) per pixel, `view_labels`
/// their labels. Reuses the outputs' storage.
void ProjectForDisplay(const core::PointCloud& cloud, const core::LabelImage& labels,
                       const core::CameraIntrinsics& intrinsics, core::PointCloud* view,
                       core::LabelImage* view_labels);

/// An image of a depth image (millimetres, 0 = invalid) for display when a frame has no
/// colour: shaded grey, near = bright, invalid pixels black. Reuses `out`'s storage.
void DepthToImage(const core::DepthImage& depth, core::ColorImage* out);

/// Draws `labels` over `base` (same size; may be null for a black base): each object's
/// pixels are blended with its LabelColor, object borders drawn solid, background dimmed.
/// Reuses `out`'s storage. O(pixels); thread-safe for distinct `out`.
void RenderOverlay(const core::LabelImage& labels, const core::ColorImage* base,
                   core::ColorImage* out);

/// One object to annotate on an overlay.
struct OverlayObject {
  uint32_t id{0};        ///< the object's label value (>= 1); its colour is LabelColor(id)
  int64_t track_id{-1};  ///< tracker identity shown as "#<track_id>"; < 0 = none
  int32_t min_u{0};      ///< image bounding box, pixels, inclusive: first column
  int32_t min_v{0};      ///< first row
  int32_t max_u{0};      ///< last column
  int32_t max_v{0};      ///< last row
};

/// The overlay objects of segmented objects: id and image bounding box of every object with
/// points, no track id. Reuses `out`'s storage.
void OverlayObjectsFrom(const std::vector<Object>& objects, std::vector<OverlayObject>* out);

/// Pixel size of one cell of the overlay's 5x7 font for a `width` x `height` image (pixels):
/// min(width, height) / 240 clamped to 1..4 (2 at 640x480).
int OverlayTextScale(int width, int height);

/// RenderOverlay(labels, base, out), then annotations a viewer can map to object ids.
/// With s = OverlayTextScale(labels.width, labels.height), all in pixels:
///
/// - every object's bounding box as a 1 px outline in its LabelColor (the part inside the
///   image; an empty box, min > max, or one wholly outside the image is skipped);
/// - a tag per object: its id in decimal digits, then "#<track_id>" when track_id >= 0, white
///   on a dark patch (s px of padding, 9s px tall, 6s px per character). The tag goes above
///   the box's top-left corner; where that is outside the image or taken by an earlier tag or
///   by the legend, inside the box's top-left corner, then below its bottom-left corner
///   (each shifted left to fit at the image's right edge), and when none is free, above
///   the box pushed into the image (it may then cover another tag);
/// - a legend of one entry per object in the order of `objects` (a 7s px swatch of the
///   object's colour, then its id in white) on a dark patch in the image corner covering the
///   fewest object pixels (ties: top-left, top-right, bottom-left, bottom-right), s px from
///   the edges. Entries fill columns top to bottom, each column at most half the image tall
///   (the whole height when the columns would not fit across the image otherwise).
///
/// The output keeps the size of `labels` (no band is added) and everything is clipped to
/// it, so any size works (a 1x1 image shows only what falls on its pixel); pixels away from
/// the annotations are exactly those of the overload above. Ids take any uint32_t value,
/// track ids any int64_t.
///
/// Allocation-free in steady state: reuses `out`'s storage and a per-thread scratch mask
/// (one byte per pixel) that grows to the largest image seen. O(pixels + objects x tag
/// area). Thread-safe for distinct `out`.
void RenderOverlay(const core::LabelImage& labels, const core::ColorImage* base,
                   const std::vector<OverlayObject>& objects, core::ColorImage* out);

}  // namespace clutterseg::pipeline
