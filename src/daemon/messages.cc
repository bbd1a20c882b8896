#include "clutterseg/daemon/messages.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>

#include "clutterseg/core/frame_limits.h"
#include "clutterseg/depth_image_t.hpp"
#include "clutterseg/label_image_codec.hpp"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/pipeline/tracker.h"
#include "clutterseg/stage_times_t.hpp"

namespace clutterseg::daemon {

namespace {

void Copy3(const core::Vec3f& v, float* out) {
  out[0] = v.x;
  out[1] = v.y;
  out[2] = v.z;
}

core::Vec3f Vec(const float* v) { return core::Vec3f{v[0], v[1], v[2]}; }

// p <- R p + t, in place.
void ApplyInPlace(const core::RigidTransform& tf, float* p) { Copy3(tf.Apply(Vec(p)), p); }

// v <- R v, in place (a direction).
void RotateInPlace(const core::RigidTransform& tf, float* v) { Copy3(tf.Rotate(Vec(v)), v); }

// The axis-aligned box around the eight transformed corners of [lo, hi], in place.
void BoxInPlace(const core::RigidTransform& tf, float* lo, float* hi) {
  float out_lo[3] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                     std::numeric_limits<float>::max()};
  float out_hi[3] = {std::numeric_limits<float>::lowest(), std::numeric_limits<float>::lowest(),
                     std::numeric_limits<float>::lowest()};
  for (int c = 0; c < 8; ++c) {
    const core::Vec3f q = tf.Apply(
        core::Vec3f{(c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1], (c & 4) ? hi[2] : lo[2]});
    const float v[3] = {q.x, q.y, q.z};
    for (int j = 0; j < 3; ++j) {
      out_lo[j] = std::min(out_lo[j], v[j]);
      out_hi[j] = std::max(out_hi[j], v[j]);
    }
  }
  std::copy(out_lo, out_lo + 3, lo);
  std::copy(out_hi, out_hi + 3, hi);
}

// The axis-aligned box around an oriented box (centre, unit axes, full extents), already in
// the parent frame.
void BoxAroundObb(const clutterseg::object_t& o, float* lo, float* hi) {
  for (int j = 0; j < 3; ++j) {
    float half = 0.f;
    for (int a = 0; a < 3; ++a) half += 0.5f * o.obb_extents[a] * std::abs(o.obb_axes[a][j]);
    lo[j] = o.obb_center[j] - half;
    hi[j] = o.obb_center[j] + half;
  }
}

void CopyIntrinsics(const core::CameraIntrinsics& k, clutterseg::intrinsics_t* out) {
  out->width = k.width;
  out->height = k.height;
  out->fx = k.fx;
  out->fy = k.fy;
  out->cx = k.cx;
  out->cy = k.cy;
}

// Thread-local scratch so steady-state encoding does not allocate.
std::vector<uint8_t>& RawScratch() {
  thread_local std::vector<uint8_t> raw;
  return raw;
}

}  // namespace

void ToObjectsMessage(const pipeline::SegmentationResult& result, const FrameInfo& info,
                      clutterseg::objects_t* msg) {
  msg->utime = info.utime;
  msg->device_utime = info.device_utime;
  msg->frame_seq = info.frame_seq;
  msg->camera_name = info.camera_name;
  CopyIntrinsics(info.intrinsics, &msg->intrinsics);
  msg->frame_id = info.camera_name;
  for (double& t : msg->camera_translation) t = 0.0;
  msg->camera_rotation_xyzw[0] = 0.0;
  msg->camera_rotation_xyzw[1] = 0.0;
  msg->camera_rotation_xyzw[2] = 0.0;
  msg->camera_rotation_xyzw[3] = 1.0;

  msg->num_planes = static_cast<int32_t>(result.planes.size());
  msg->planes.resize(result.planes.size());
  for (size_t i = 0; i < result.planes.size(); ++i) {
    const pipeline::Plane& in = result.planes[i];
    clutterseg::plane_t& out = msg->planes[i];
    out.id = static_cast<int32_t>(in.id);
    Copy3(in.normal, out.normal);
    out.d = in.d;
    out.num_points = static_cast<int32_t>(in.num_points);
    out.is_support = in.is_support;
  }

  msg->num_objects = static_cast<int32_t>(result.objects.size());
  msg->objects.resize(result.objects.size());
  for (size_t i = 0; i < result.objects.size(); ++i) {
    const pipeline::Object& in = result.objects[i];
    clutterseg::object_t& out = msg->objects[i];
    out.id = static_cast<int32_t>(in.id);
    out.num_points = static_cast<int32_t>(in.num_points);
    Copy3(in.centroid, out.centroid);
    Copy3(in.aabb_min, out.aabb_min);
    Copy3(in.aabb_max, out.aabb_max);
    Copy3(in.obb_center, out.obb_center);
    for (int a = 0; a < 3; ++a) Copy3(in.obb_axes[a], out.obb_axes[a]);
    Copy3(in.obb_extents, out.obb_extents);
    out.support_plane_id = in.support_plane_id;
    out.has_gravity_box = in.has_gravity_box;
    Copy3(in.gbox_center, out.gbox_center);
    for (int a = 0; a < 3; ++a) Copy3(in.gbox_axes[a], out.gbox_axes[a]);
    Copy3(in.gbox_extents, out.gbox_extents);
    out.height_m = in.height_m;
    out.bottom_m = in.bottom_m;
    out.mean_color[0] = in.mean_color.r;
    out.mean_color[1] = in.mean_color.g;
    out.mean_color[2] = in.mean_color.b;
    out.confidence = in.confidence;
    out.bbox_min_u = in.pixel_min_u;
    out.bbox_min_v = in.pixel_min_v;
    out.bbox_max_u = in.pixel_max_u;
    out.bbox_max_v = in.pixel_max_v;
    out.track_id = -1;
    out.track_age_frames = 0;
    out.track_seen_frames = 0;
    out.track_state = clutterseg::object_t::TRACK_NEW;
    out.track_reacquired = false;
    out.num_samples = 0;
    out.samples.clear();
  }
  msg->num_lost_tracks = 0;
  msg->lost_tracks.clear();
  msg->num_ended_tracks = 0;
  msg->ended_track_ids.clear();
  msg->tracks_reset = false;
  msg->tracker_ms = 0.f;

  msg->num_valid_points = static_cast<int32_t>(result.num_valid_points);
  msg->num_supervoxels = static_cast<int32_t>(result.num_supervoxels);
  ToStageTimesMessage(result.times, &msg->times);
}

void ToStageTimesMessage(const pipeline::StageTimes& times, clutterseg::stage_times_t* msg) {
  msg->num_stages = static_cast<int32_t>(pipeline::kNumStages);
  msg->stage_names.resize(pipeline::kNumStages);
  msg->stage_ms.resize(pipeline::kNumStages);
  for (size_t i = 0; i < pipeline::kNumStages; ++i) {
    const std::string_view name = pipeline::StageTable()[i].name;
    if (msg->stage_names[i] != name) msg->stage_names[i].assign(name);
    msg->stage_ms[i] = static_cast<float>(times.ms[i]);
  }
  msg->total_ms = static_cast<float>(times.total_ms);
}

const char* ToString(LabelCompression compression) {
  switch (compression) {
    case LabelCompression::kNone:
      return "none";
    case LabelCompression::kRle:
      return "rle";
    case LabelCompression::kZlib:
      return "zlib";
  }
  return "zlib";
}

void EncodeLabelImage(const core::LabelImage& labels, const FrameInfo& info,
                      LabelCompression compression, clutterseg::label_image_t* msg) {
  msg->utime = info.utime;
  msg->device_utime = info.device_utime;
  msg->frame_seq = info.frame_seq;
  msg->camera_name = info.camera_name;
  int8_t code = clutterseg::label_image_t::COMPRESSION_RLE;
  if (compression == LabelCompression::kNone) code = clutterseg::label_image_t::COMPRESSION_NONE;
  if (compression == LabelCompression::kZlib) code = clutterseg::label_image_t::COMPRESSION_ZLIB;
  std::string error;
  if (!clutterseg::EncodeLabelImage(labels.data.data(), labels.width, labels.height, code, msg,
                                    &RawScratch(), &error)) {
    throw std::runtime_error(error);
  }
}

void DecodeLabelImage(const clutterseg::label_image_t& msg, core::LabelImage* labels) {
  // The frame limits of every reader (core::FrameLimits), checked before anything is
  // allocated: a hostile message is an error, not an allocation (the codec checks the rest).
  if (msg.width > 0 && msg.height > 0) {
    if (const std::optional<std::string> too_large =
            core::FrameLimits{}.CheckImage(msg.width, msg.height, sizeof(uint32_t))) {
      labels->Reset(0, 0);
      throw std::runtime_error("label_image_t: declared size " + *too_large);
    }
    // Deflate expands by at most 1032:1: a short stream cannot hold a large image.
    const uint64_t raw_bytes =
        2 * static_cast<uint64_t>(msg.width) * static_cast<uint64_t>(msg.height);
    if (msg.compression == clutterseg::label_image_t::COMPRESSION_ZLIB &&
        raw_bytes > 1032 * static_cast<uint64_t>(msg.data.size()) + 1024) {
      labels->Reset(0, 0);
      throw std::runtime_error("label_image_t: " + std::to_string(msg.data.size()) +
                               " zlib bytes cannot hold " + std::to_string(raw_bytes / 2) +
                               " labels");
    }
  }
  std::string error;
  if (!clutterseg::DecodeLabelImage(msg, &labels->data, &error)) {
    labels->Reset(0, 0);
    throw std::runtime_error(error);
  }
  labels->width = msg.width;
  labels->height = msg.height;
}

void ToTrackMessage(const pipeline::TrackingResult& tracking, clutterseg::objects_t* msg) {
  const size_t n = std::min(tracking.objects.size(), msg->objects.size());
  for (size_t i = 0; i < n; ++i) {
    const pipeline::ObjectTrack& t = tracking.objects[i];
    clutterseg::object_t& o = msg->objects[i];
    o.track_id = t.track_id;
    o.track_age_frames = t.age_frames;
    o.track_seen_frames = t.seen_frames;
    o.track_state = t.state == pipeline::TrackState::kConfirmed
                        ? clutterseg::object_t::TRACK_CONFIRMED
                        : clutterseg::object_t::TRACK_NEW;
    o.track_reacquired = t.reacquired;
  }
  msg->num_lost_tracks = static_cast<int32_t>(tracking.lost.size());
  msg->lost_tracks.resize(tracking.lost.size());
  for (size_t i = 0; i < tracking.lost.size(); ++i) {
    const pipeline::LostTrack& in = tracking.lost[i];
    clutterseg::lost_track_t& out = msg->lost_tracks[i];
    out.track_id = in.track_id;
    out.frames_since_seen = in.frames_since_seen;
    out.track_age_frames = in.age_frames;
    out.track_seen_frames = in.seen_frames;
    out.was_confirmed = in.was_confirmed;
    out.num_points = static_cast<int32_t>(in.num_points);
    Copy3(in.centroid, out.centroid);
    Copy3(in.aabb_min, out.aabb_min);
    Copy3(in.aabb_max, out.aabb_max);
    Copy3(in.remembered_min, out.remembered_min);
    Copy3(in.remembered_max, out.remembered_max);
  }
  msg->num_ended_tracks = static_cast<int32_t>(tracking.ended_track_ids.size());
  msg->ended_track_ids.assign(tracking.ended_track_ids.begin(), tracking.ended_track_ids.end());
  msg->tracks_reset = tracking.reset;
  msg->tracker_ms = static_cast<float>(tracking.time_ms);
}

void ToParentFrame(const core::Extrinsics& extrinsics, const core::PointCloud& cloud,
                   const core::LabelImage& labels, clutterseg::objects_t* msg) {
  const core::RigidTransform tf = core::RigidTransform::Of(extrinsics);
  msg->frame_id = extrinsics.parent_frame;
  core::Extrinsics pose = extrinsics;
  pose.Normalize();
  std::copy(pose.translation_m, pose.translation_m + 3, msg->camera_translation);
  std::copy(pose.rotation_xyzw, pose.rotation_xyzw + 4, msg->camera_rotation_xyzw);
  for (clutterseg::plane_t& p : msg->planes) {
    RotateInPlace(tf, p.normal);
    p.d -= p.normal[0] * tf.t[0] + p.normal[1] * tf.t[1] + p.normal[2] * tf.t[2];
  }
  for (clutterseg::object_t& o : msg->objects) {
    ApplyInPlace(tf, o.centroid);
    ApplyInPlace(tf, o.obb_center);
    for (auto& axis : o.obb_axes) RotateInPlace(tf, axis);
    if (o.has_gravity_box) {
      ApplyInPlace(tf, o.gbox_center);
      for (auto& axis : o.gbox_axes) RotateInPlace(tf, axis);
    }
    for (auto& p : o.samples) ApplyInPlace(tf, p.data());
  }
  // Axis-aligned boxes from the points themselves, in the parent frame.
  const size_t num_objects = msg->objects.size();
  if (cloud.xyz.size() != labels.data.size()) {
    for (clutterseg::object_t& o : msg->objects) BoxAroundObb(o, o.aabb_min, o.aabb_max);
    return;
  }
  for (clutterseg::object_t& o : msg->objects) {
    std::fill(o.aabb_min, o.aabb_min + 3, std::numeric_limits<float>::max());
    std::fill(o.aabb_max, o.aabb_max + 3, std::numeric_limits<float>::lowest());
  }
  for (size_t i = 0; i < labels.data.size(); ++i) {
    const uint32_t l = labels.data[i];
    if (l == 0 || l > num_objects || !core::IsValid(cloud.xyz[i])) continue;
    clutterseg::object_t& o = msg->objects[l - 1];
    const core::Vec3f q = tf.Apply(cloud.xyz[i]);
    o.aabb_min[0] = std::min(o.aabb_min[0], q.x);
    o.aabb_min[1] = std::min(o.aabb_min[1], q.y);
    o.aabb_min[2] = std::min(o.aabb_min[2], q.z);
    o.aabb_max[0] = std::max(o.aabb_max[0], q.x);
    o.aabb_max[1] = std::max(o.aabb_max[1], q.y);
    o.aabb_max[2] = std::max(o.aabb_max[2], q.z);
  }
  for (clutterseg::object_t& o : msg->objects) {
    if (o.aabb_min[0] > o.aabb_max[0]) BoxAroundObb(o, o.aabb_min, o.aabb_max);  // no point
  }
}

void LostTracksToParentFrame(const core::Extrinsics& extrinsics, clutterseg::objects_t* msg) {
  const core::RigidTransform tf = core::RigidTransform::Of(extrinsics);
  for (clutterseg::lost_track_t& t : msg->lost_tracks) {
    ApplyInPlace(tf, t.centroid);
    BoxInPlace(tf, t.aabb_min, t.aabb_max);
    BoxInPlace(tf, t.remembered_min, t.remembered_max);
  }
}

void SampleObjectPoints(const core::PointCloud& cloud, const core::LabelImage& labels,
                        int max_per_object, clutterseg::objects_t* msg) {
  const size_t num_objects = msg->objects.size();
  for (clutterseg::object_t& o : msg->objects) {
    o.num_samples = 0;
    o.samples.clear();
  }
  if (max_per_object <= 0 || num_objects == 0 || cloud.xyz.size() != labels.data.size()) return;
  // Every stride-th point of an object, so that its samples spread over the whole object.
  thread_local std::vector<uint32_t> seen;
  seen.assign(num_objects, 0);
  for (clutterseg::object_t& o : msg->objects)
    o.samples.reserve(static_cast<size_t>(max_per_object));
  for (size_t i = 0; i < labels.data.size(); ++i) {
    const uint32_t l = labels.data[i];
    if (l == 0 || l > num_objects) continue;
    clutterseg::object_t& o = msg->objects[l - 1];
    const auto points = static_cast<uint32_t>(std::max(o.num_points, 1));
    const uint32_t stride = (points + static_cast<uint32_t>(max_per_object) - 1) /
                            static_cast<uint32_t>(max_per_object);
    const core::Vec3f& p = cloud.xyz[i];
    if (seen[l - 1]++ % stride != 0 || o.num_samples >= max_per_object || !core::IsValid(p)) {
      continue;
    }
    o.samples.push_back({p.x, p.y, p.z});
    ++o.num_samples;
  }
}

void EncodeDepthImage(const core::DepthImage& depth, const FrameInfo& info, bool compress,
                      clutterseg::depth_image_t* msg) {
  msg->utime = info.utime;
  msg->device_utime = info.device_utime;
  msg->frame_seq = info.frame_seq;
  msg->camera_name = info.camera_name;
  CopyIntrinsics(info.intrinsics, &msg->intrinsics);
  msg->width = depth.width;
  msg->height = depth.height;
  std::vector<uint8_t>& raw = compress ? RawScratch() : msg->data;
  raw.resize(depth.data.size() * 2);
  for (size_t i = 0; i < depth.data.size(); ++i) {
    raw[2 * i] = static_cast<uint8_t>(depth.data[i] & 0xff);
    raw[2 * i + 1] = static_cast<uint8_t>(depth.data[i] >> 8);
  }
  if (compress) {
    msg->compression = clutterseg::depth_image_t::COMPRESSION_ZLIB;
    uLongf size = compressBound(static_cast<uLong>(raw.size()));
    msg->data.resize(size);
    if (compress2(msg->data.data(), &size, raw.data(), static_cast<uLong>(raw.size()), 1) != Z_OK) {
      throw std::runtime_error("depth image: zlib compress2 failed");
    }
    msg->data.resize(size);
  } else {
    msg->compression = clutterseg::depth_image_t::COMPRESSION_NONE;
  }
  msg->size = static_cast<int32_t>(msg->data.size());
}

}  // namespace clutterseg::daemon
