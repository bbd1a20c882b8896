#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
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
/// (track_id -1, no lost or ended tracks) and no point samples. Timing fields other than the
/// stage times (queue_ms, capture_to_publish_ms, tracker_ms) are left for the caller.
void ToObjectsMessage(const pipeline::SegmentationResult& result, const FrameInfo& info,
                      clutterseg::objects_t* msg);

/// Writes a frame's tracking into `msg` (filled by ToObjectsMessage for the same frame): each
/// object's track fields, the lost and the ended tracks, tracks_reset and tracker_ms.
void ToTrackMessage(const pipeline::TrackingResult& tracking, clutterseg::objects_t* msg);

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
