#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/extrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"
#include "clutterseg/pipeline/segmentation_result.h"

namespace clutterseg {
class objects_t;
class label_image_t;
class depth_image_t;
class stage_times_t;
}  // namespace clutterseg

namespace clutterseg::pipeline {
struct TrackingResult;
}  // namespace clutterseg::pipeline

namespace clutterseg::daemon {

/// Encoding of label_image_t payloads.
enum class LabelCompression { kNone, kRle, kZlib };
const char* ToString(LabelCompression compression);

/// Frame metadata carried into the messages of one frame.
struct FrameInfo {
  int64_t utime{0};         ///< host time of capture, microseconds since the epoch
  int64_t device_utime{0};  ///< the source's timestamp of the frame, microseconds
  int64_t frame_seq{0};     ///< source frame number
  std::string camera_name;
  core::CameraIntrinsics intrinsics;
};

/// Fills an objects_t from one frame's segmentation, reusing `msg`'s vectors, with no track
/// (track_id -1, no lost or ended tracks) and no point samples, in the camera frame: frame_id
/// = camera_name, the camera's pose the identity. Timing fields other than the stage times
/// (queue_ms, capture_to_publish_ms, tracker_ms) are left for the caller.
void ToObjectsMessage(const pipeline::SegmentationResult& result, const FrameInfo& info,
                      clutterseg::objects_t* msg);

/// Writes a frame's tracking into `msg` (filled by ToObjectsMessage for the same frame): each
/// object's track fields, the lost and the ended tracks, tracks_reset and tracker_ms.
void ToTrackMessage(const pipeline::TrackingResult& tracking, clutterseg::objects_t* msg);

/// Expresses the frame's geometry in the parent frame of `extrinsics` (p_parent = R p_cam + t):
/// `msg` filled by ToObjectsMessage (and SampleObjectPoints) in the camera frame gets
/// frame_id = extrinsics.parent_frame, the camera's pose, and R and t applied to the planes
/// (n' = R n, d' = d - n'.t), the objects' centroids, oriented and gravity-aligned boxes
/// (centre and axes; extents and heights are unchanged) and samples. The axis-aligned boxes
/// are recomputed from the objects' points in the parent frame (the points of `cloud` that
/// `labels` labels; a box around the rotated oriented box when the two differ in size). Lost
/// tracks are left to LostTracksToParentFrame. O(points).
void ToParentFrame(const core::Extrinsics& extrinsics, const core::PointCloud& cloud,
                   const core::LabelImage& labels, clutterseg::objects_t* msg);

/// Expresses `msg`'s lost tracks (written by ToTrackMessage, camera frame) in the parent frame
/// of `extrinsics`: centroids transformed, each box (last view, remembered) replaced by the
/// axis-aligned box around its eight transformed corners.
void LostTracksToParentFrame(const core::Extrinsics& extrinsics, clutterseg::objects_t* msg);

/// Fills each object's samples with at most `max_per_object` of its points (metres), evenly
/// subsampled in point order from `cloud` (the cloud `labels` labels). O(points).
void SampleObjectPoints(const core::PointCloud& cloud, const core::LabelImage& labels,
                        int max_per_object, clutterseg::objects_t* msg);

/// Encodes a depth image (millimetres) into a depth_image_t, deflated with zlib (level 1)
/// when `compress`, reusing `msg`'s buffer. @throws std::runtime_error when zlib fails.
void EncodeDepthImage(const core::DepthImage& depth, const FrameInfo& info, bool compress,
                      clutterseg::depth_image_t* msg);

/// Encodes a label image (ids must fit in uint16; larger ones are clamped to 65535) into a
/// label_image_t with the given compression, reusing `msg`'s buffer.
/// @throws std::runtime_error when zlib fails.
void EncodeLabelImage(const core::LabelImage& labels, const FrameInfo& info,
                      LabelCompression compression, clutterseg::label_image_t* msg);

/// Decodes any label_image_t compression back into a label image.
/// @throws std::runtime_error naming the problem when the message is malformed.
void DecodeLabelImage(const clutterseg::label_image_t& msg, core::LabelImage* labels);

/// Fills a stage_times_t from one frame's stage times (pipeline::StageTable() order).
void ToStageTimesMessage(const pipeline::StageTimes& times, clutterseg::stage_times_t* msg);

}  // namespace clutterseg::daemon
