#include "clutterseg/daemon/messages.h"

#include <cstring>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/intrinsics_t.hpp"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/object_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/plane_t.hpp"
#include "clutterseg/stage_times_t.hpp"
#include "clutterseg/status_t.hpp"

namespace clutterseg::daemon {
namespace {

template <typename T>
T RoundTrip(const T& in) {
  const int size = in.getEncodedSize();
  std::vector<uint8_t> buf(static_cast<size_t>(size));
  EXPECT_EQ(in.encode(buf.data(), 0, size), size);
  T out;
  EXPECT_EQ(out.decode(buf.data(), 0, size), size);
  // A truncated buffer must be rejected, not read past its end.
  T bad;
  EXPECT_LT(bad.decode(buf.data(), 0, size - 1), 0);
  return out;
}

clutterseg::object_t SampleObject(int id) {
  clutterseg::object_t o{};
  o.id = id;
  o.num_points = 1000 + id;
  for (int i = 0; i < 3; ++i) {
    o.centroid[i] = 0.1f * static_cast<float>(i + id);
    o.aabb_min[i] = -0.5f + static_cast<float>(i);
    o.aabb_max[i] = 0.5f + static_cast<float>(i);
    o.obb_center[i] = 0.25f * static_cast<float>(i);
    o.obb_extents[i] = 0.01f * static_cast<float>(i + 1);
    for (int j = 0; j < 3; ++j) o.obb_axes[i][j] = i == j ? 1.f : 0.f;
    o.mean_color[i] = static_cast<uint8_t>(40 * i + 7);
  }
  o.support_plane_id = 2;
  o.confidence = 0.75f;
  o.bbox_min_u = 10;
  o.bbox_min_v = 20;
  o.bbox_max_u = 30 + id;
  o.bbox_max_v = 40;
  o.track_id = 1000 + id;
  o.track_state = clutterseg::object_t::TRACK_CONFIRMED;
  o.num_samples = 2;
  o.samples = {{0.1f, 0.2f, 0.9f}, {0.15f, 0.25f, 0.95f}};
  return o;
}

TEST(LcmTypes, IntrinsicsPlaneObjectStageTimesRoundTrip) {
  clutterseg::intrinsics_t k{};
  k.width = 640;
  k.height = 480;
  k.fx = 525.5;
  k.fy = 524.25;
  k.cx = 319.5;
  k.cy = 239.5;
  const auto k2 = RoundTrip(k);
  EXPECT_EQ(k2.width, 640);
  EXPECT_EQ(k2.fy, 524.25);
  EXPECT_EQ(k2.cy, 239.5);

  clutterseg::plane_t p{};
  p.id = 3;
  p.normal[0] = 0.f;
  p.normal[1] = -0.8f;
  p.normal[2] = -0.6f;
  p.d = 1.25f;
  p.num_points = 50000;
  p.is_support = true;
  const auto p2 = RoundTrip(p);
  EXPECT_EQ(p2.id, 3);
  EXPECT_EQ(p2.normal[1], -0.8f);
  EXPECT_EQ(p2.d, 1.25f);
  EXPECT_TRUE(p2.is_support);

  const auto o2 = RoundTrip(SampleObject(5));
  EXPECT_EQ(o2.id, 5);
  EXPECT_EQ(o2.num_points, 1005);
  EXPECT_EQ(o2.centroid[2], 0.1f * 7);
  EXPECT_EQ(o2.obb_axes[1][1], 1.f);
  EXPECT_EQ(o2.mean_color[2], 87);
  EXPECT_EQ(o2.bbox_max_u, 35);
  EXPECT_EQ(o2.support_plane_id, 2);

  pipeline::StageTimes times;
  times[pipeline::Stage::kVoxelize] = 4.5;
  times.total_ms = 21.0;
  clutterseg::stage_times_t t{};
  ToStageTimesMessage(times, &t);
  const auto t2 = RoundTrip(t);
  ASSERT_EQ(t2.num_stages, static_cast<int32_t>(pipeline::kNumStages));
  // Named after the segmenter's stage table, in its order.
  for (size_t i = 0; i < pipeline::kNumStages; ++i) {
    EXPECT_EQ(t2.stage_names[i], pipeline::StageTable()[i].name);
  }
  EXPECT_EQ(t2.stage_ms[static_cast<size_t>(pipeline::Stage::kVoxelize)], 4.5f);
  EXPECT_EQ(t2.total_ms, 21.f);
}

TEST(LcmTypes, ObjectsRoundTrip) {
  clutterseg::objects_t m{};
  m.utime = 1234567890123;
  m.frame_seq = 42;
  m.camera_name = "head_camera";
  m.intrinsics.width = 640;
  m.num_planes = 2;
  m.planes.resize(2);
  m.planes[1].id = 9;
  m.num_objects = 3;
  m.objects = {SampleObject(1), SampleObject(2), SampleObject(3)};
  m.num_lost_tracks = 1;
  m.lost_tracks.resize(1);
  m.lost_tracks[0].track_id = 7;
  m.num_ended_tracks = 2;
  m.ended_track_ids = {5, 6};
  m.num_valid_points = 250000;
  m.num_supervoxels = 800;
  m.times.total_ms = 30.f;
  m.queue_ms = 1.5f;
  m.capture_to_publish_ms = 35.f;
  const auto m2 = RoundTrip(m);
  EXPECT_EQ(m2.utime, 1234567890123);
  EXPECT_EQ(m2.frame_seq, 42);
  EXPECT_EQ(m2.camera_name, "head_camera");
  EXPECT_EQ(m2.planes.size(), 2u);
  EXPECT_EQ(m2.planes[1].id, 9);
  ASSERT_EQ(m2.objects.size(), 3u);
  EXPECT_EQ(m2.objects[2].id, 3);
  EXPECT_EQ(m2.objects[2].track_id, 1003);
  ASSERT_EQ(m2.objects[2].num_samples, 2);
  EXPECT_EQ(m2.objects[2].samples[1][2], 0.95f);
  ASSERT_EQ(m2.num_lost_tracks, 1);
  EXPECT_EQ(m2.lost_tracks[0].track_id, 7);
  ASSERT_EQ(m2.ended_track_ids, (std::vector<int64_t>{5, 6}));
  EXPECT_EQ(m2.num_supervoxels, 800);
  EXPECT_EQ(m2.capture_to_publish_ms, 35.f);
}

TEST(LcmTypes, StatusRoundTrip) {
  clutterseg::status_t s{};
  s.utime = 99;
  s.camera_name = "camera";
  s.source = "oni:/x.oni";
  s.fps = 29.5f;
  s.segment_p99_ms = 40.f;
  s.num_stages = 2;
  s.stage_names = {"voxelize", "planes"};
  s.stage_p50_ms = {1.f, 2.f};
  s.stage_p99_ms = {3.f, 4.f};
  s.queue_depth = 1;
  s.frames_dropped = 7;
  s.device_state = clutterseg::status_t::DEVICE_RECONNECTING;
  s.device_state_name = "reconnecting";
  s.reconnect_attempts = 3;
  s.last_error = "device lost";
  const auto s2 = RoundTrip(s);
  EXPECT_EQ(s2.stage_names[1], "planes");
  EXPECT_EQ(s2.stage_p99_ms[1], 4.f);
  EXPECT_EQ(s2.frames_dropped, 7);
  EXPECT_EQ(s2.device_state, clutterseg::status_t::DEVICE_RECONNECTING);
  EXPECT_EQ(s2.last_error, "device lost");
}

core::LabelImage SampleLabels(int w, int h) {
  core::LabelImage labels(w, h, 0);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      if (u > w / 4 && u < w / 2 && v > h / 3) labels.at(u, v) = 1;
      if (u > 2 * w / 3 && v < h / 2) labels.at(u, v) = 2 + (u % 3 == 0 ? 1 : 0);
    }
  }
  labels.at(w - 1, h - 1) = 70000;  // does not fit uint16: clamped
  return labels;
}

TEST(LabelImage, EveryCompressionRoundTripsThroughLcm) {
  const core::LabelImage labels = SampleLabels(64, 48);
  FrameInfo info;
  info.utime = 5;
  info.frame_seq = 6;
  info.camera_name = "cam";
  for (auto c : {LabelCompression::kNone, LabelCompression::kRle, LabelCompression::kZlib}) {
    clutterseg::label_image_t msg;
    EncodeLabelImage(labels, info, c, &msg);
    EXPECT_EQ(msg.size, static_cast<int32_t>(msg.data.size()));
    const auto back = RoundTrip(msg);
    EXPECT_EQ(back.frame_seq, 6);
    EXPECT_EQ(back.width, 64);
    core::LabelImage decoded;
    DecodeLabelImage(back, &decoded);
    ASSERT_EQ(decoded.width, 64);
    ASSERT_EQ(decoded.height, 48);
    for (size_t i = 0; i + 1 < labels.data.size(); ++i) {
      ASSERT_EQ(decoded.data[i], labels.data[i]) << "pixel " << i << " compression " << ToString(c);
    }
    EXPECT_EQ(decoded.data.back(), 65535u);
  }
  clutterseg::label_image_t none, zlib;
  EncodeLabelImage(labels, info, LabelCompression::kNone, &none);
  EncodeLabelImage(labels, info, LabelCompression::kZlib, &zlib);
  EXPECT_EQ(none.data.size(), 64u * 48u * 2u);
  EXPECT_LT(zlib.data.size(), none.data.size() / 4);
}

TEST(LabelImage, RleRunsFollowTheClampedIds) {
  // One row: 7 ones, four distinct ids that all clamp to 65535, 13 twos, one 3. The run
  // scan compares four ids at a time, so the runs end at every offset modulo four.
  std::vector<uint32_t> row(7, 1u);
  for (uint32_t big : {70000u, 70001u, 65535u, 65536u}) row.push_back(big);
  row.insert(row.end(), 13, 2u);
  row.push_back(3u);
  core::LabelImage labels;
  labels.Reset(static_cast<int>(row.size()), 1, 0u);
  labels.data = row;
  clutterseg::label_image_t msg;
  EncodeLabelImage(labels, FrameInfo{}, LabelCompression::kRle, &msg);
  ASSERT_EQ(msg.data.size(), 4u * 6u);  // runs of 1, 65535, 2 and 3
  const uint32_t expected_runs[4][2] = {{1, 7}, {65535, 4}, {2, 13}, {3, 1}};
  for (size_t k = 0; k < 4; ++k) {
    const uint8_t* p = msg.data.data() + 6 * k;
    EXPECT_EQ(p[0] | (p[1] << 8), static_cast<int>(expected_runs[k][0])) << "run " << k;
    EXPECT_EQ(p[2] | (p[3] << 8) | (p[4] << 16) | (p[5] << 24),
              static_cast<int>(expected_runs[k][1]))
        << "run " << k;
  }
  core::LabelImage decoded;
  DecodeLabelImage(RoundTrip(msg), &decoded);
  ASSERT_EQ(decoded.data.size(), row.size());
  for (size_t i = 0; i < row.size(); ++i) {
    EXPECT_EQ(decoded.data[i], std::min(row[i], 65535u)) << "pixel " << i;
  }
}

TEST(LabelImage, MalformedMessagesAreRejected) {
  const core::LabelImage labels = SampleLabels(16, 8);
  FrameInfo info;
  clutterseg::label_image_t msg;
  core::LabelImage out;
  EncodeLabelImage(labels, info, LabelCompression::kRle, &msg);
  msg.data.pop_back();
  msg.size = static_cast<int32_t>(msg.data.size());
  EXPECT_THROW(DecodeLabelImage(msg, &out), std::runtime_error);

  EncodeLabelImage(labels, info, LabelCompression::kZlib, &msg);
  msg.data[msg.data.size() / 2] ^= 0xff;
  msg.data.resize(msg.data.size() - 3);
  msg.size = static_cast<int32_t>(msg.data.size());
  EXPECT_THROW(DecodeLabelImage(msg, &out), std::runtime_error);

  EncodeLabelImage(labels, info, LabelCompression::kNone, &msg);
  msg.width = 17;  // size no longer matches
  EXPECT_THROW(DecodeLabelImage(msg, &out), std::runtime_error);

  EncodeLabelImage(labels, info, LabelCompression::kNone, &msg);
  msg.compression = 9;
  EXPECT_THROW(DecodeLabelImage(msg, &out), std::runtime_error);
}

TEST(ObjectsMessage, CopiesTheSegmentation) {
  pipeline::SegmentationResult r;
  r.width = 4;
  r.height = 2;
  r.num_valid_points = 8;
  r.num_supervoxels = 2;
  r.times[pipeline::Stage::kPlanes] = 2.5;
  pipeline::Plane plane;
  plane.id = 1;
  plane.normal = {0.f, -1.f, 0.f};
  plane.d = 0.7f;
  plane.num_points = 5;
  plane.is_support = true;
  r.planes.push_back(plane);
  pipeline::Object obj;
  obj.id = 1;
  obj.num_points = 3;
  obj.centroid = {0.1f, 0.2f, 0.9f};
  obj.obb_axes[2] = {0.f, 0.f, 1.f};
  obj.support_plane_id = 1;
  obj.mean_color = {10, 20, 30};
  obj.pixel_max_u = 3;
  r.objects.push_back(obj);
  FrameInfo info;
  info.utime = 77;
  info.frame_seq = 8;
  info.camera_name = "c";
  info.intrinsics.fx = 500.0;
  clutterseg::objects_t m;
  ToObjectsMessage(r, info, &m);
  EXPECT_EQ(m.utime, 77);
  EXPECT_EQ(m.frame_seq, 8);
  EXPECT_EQ(m.intrinsics.fx, 500.0);
  ASSERT_EQ(m.num_planes, 1);
  EXPECT_EQ(m.planes[0].normal[1], -1.f);
  EXPECT_TRUE(m.planes[0].is_support);
  ASSERT_EQ(m.num_objects, 1);
  EXPECT_EQ(m.objects[0].centroid[2], 0.9f);
  EXPECT_EQ(m.objects[0].obb_axes[2][2], 1.f);
  EXPECT_EQ(m.objects[0].mean_color[1], 20);
  EXPECT_EQ(m.objects[0].bbox_max_u, 3);
  EXPECT_EQ(m.times.stage_ms[static_cast<size_t>(pipeline::Stage::kPlanes)], 2.5f);
  // Buffers are reused: a smaller result shrinks the arrays.
  r.objects.clear();
  ToObjectsMessage(r, info, &m);
  EXPECT_EQ(m.num_objects, 0);
  EXPECT_TRUE(m.objects.empty());
}

}  // namespace
}  // namespace clutterseg::daemon
