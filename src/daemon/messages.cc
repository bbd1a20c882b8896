#include "clutterseg/daemon/messages.h"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <optional>
#include <stdexcept>

#include "clutterseg/core/frame_limits.h"
#include "clutterseg/label_image_t.hpp"
#include "clutterseg/objects_t.hpp"
#include "clutterseg/stage_times_t.hpp"

namespace clutterseg::daemon {

namespace {

void Copy3(const core::Vec3f& v, float* out) {
  out[0] = v.x;
  out[1] = v.y;
  out[2] = v.z;
}

uint16_t ClampLabel(uint32_t label) {
  return static_cast<uint16_t>(std::min<uint32_t>(label, 65535u));
}

void PutU16(uint16_t v, std::vector<uint8_t>* out) {
  out->push_back(static_cast<uint8_t>(v & 0xff));
  out->push_back(static_cast<uint8_t>(v >> 8));
}

void PutU32(uint32_t v, std::vector<uint8_t>* out) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<uint8_t>((v >> (8 * i)) & 0xff));
}

uint16_t GetU16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t GetU32(const uint8_t* p) {
  return uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24);
}

// Thread-local scratch so steady-state encoding does not allocate.
std::vector<uint8_t>& RawScratch() {
  thread_local std::vector<uint8_t> raw;
  return raw;
}

void RawLabels(const core::LabelImage& labels, std::vector<uint8_t>* raw) {
  raw->resize(labels.data.size() * 2);
  uint8_t* p = raw->data();
  for (uint32_t l : labels.data) {
    const uint16_t v = ClampLabel(l);
    *p++ = static_cast<uint8_t>(v & 0xff);
    *p++ = static_cast<uint8_t>(v >> 8);
  }
}

}  // namespace

void ToObjectsMessage(const pipeline::SegmentationResult& result, const FrameInfo& info,
                      clutterseg::objects_t* msg) {
  msg->utime = info.utime;
  msg->frame_seq = info.frame_seq;
  msg->camera_name = info.camera_name;
  msg->intrinsics.width = info.intrinsics.width;
  msg->intrinsics.height = info.intrinsics.height;
  msg->intrinsics.fx = info.intrinsics.fx;
  msg->intrinsics.fy = info.intrinsics.fy;
  msg->intrinsics.cx = info.intrinsics.cx;
  msg->intrinsics.cy = info.intrinsics.cy;

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
    out.mean_color[0] = in.mean_color.r;
    out.mean_color[1] = in.mean_color.g;
    out.mean_color[2] = in.mean_color.b;
    out.confidence = in.confidence;
    out.bbox_min_u = in.pixel_min_u;
    out.bbox_min_v = in.pixel_min_v;
    out.bbox_max_u = in.pixel_max_u;
    out.bbox_max_v = in.pixel_max_v;
  }

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
  msg->frame_seq = info.frame_seq;
  msg->camera_name = info.camera_name;
  msg->width = labels.width;
  msg->height = labels.height;
  std::vector<uint8_t>& data = msg->data;
  data.clear();
  switch (compression) {
    case LabelCompression::kNone:
      msg->compression = clutterseg::label_image_t::COMPRESSION_NONE;
      RawLabels(labels, &data);
      break;
    case LabelCompression::kRle: {
      msg->compression = clutterseg::label_image_t::COMPRESSION_RLE;
      size_t i = 0;
      while (i < labels.data.size()) {
        const uint16_t v = ClampLabel(labels.data[i]);
        size_t j = i + 1;
        while (j < labels.data.size() && ClampLabel(labels.data[j]) == v && j - i < UINT32_MAX) ++j;
        PutU16(v, &data);
        PutU32(static_cast<uint32_t>(j - i), &data);
        i = j;
      }
      break;
    }
    case LabelCompression::kZlib: {
      msg->compression = clutterseg::label_image_t::COMPRESSION_ZLIB;
      std::vector<uint8_t>& raw = RawScratch();
      RawLabels(labels, &raw);
      uLongf size = compressBound(static_cast<uLong>(raw.size()));
      data.resize(size);
      if (compress2(data.data(), &size, raw.data(), static_cast<uLong>(raw.size()), 1) != Z_OK) {
        throw std::runtime_error("label image: zlib compress2 failed");
      }
      data.resize(size);
      break;
    }
  }
  msg->size = static_cast<int32_t>(data.size());
}

void DecodeLabelImage(const clutterseg::label_image_t& msg, core::LabelImage* labels) {
  // Every size the message declares is checked before anything is allocated: a hostile
  // message is an error, not an allocation. The image must fit the frame limits of every
  // reader (core::FrameLimits; 0 x 0 is an empty frame).
  if (msg.width < 0 || msg.height < 0) {
    throw std::runtime_error("label_image_t: bad size " + std::to_string(msg.width) + "x" +
                             std::to_string(msg.height));
  }
  const bool empty = msg.width == 0 || msg.height == 0;
  if (!empty) {
    if (const std::optional<std::string> too_large =
            core::FrameLimits{}.CheckImage(msg.width, msg.height, sizeof(uint32_t))) {
      throw std::runtime_error("label_image_t: declared size " + *too_large);
    }
  }
  if (msg.size != static_cast<int32_t>(msg.data.size())) {
    throw std::runtime_error("label_image_t: size field " + std::to_string(msg.size) +
                             " != data length " + std::to_string(msg.data.size()));
  }
  const size_t n = empty ? 0 : static_cast<size_t>(msg.width) * static_cast<size_t>(msg.height);
  auto from_raw = [&](const uint8_t* raw, size_t bytes) {
    if (bytes != 2 * n) {
      throw std::runtime_error("label_image_t: " + std::to_string(bytes) + " label bytes for " +
                               std::to_string(n) + " pixels");
    }
    labels->Reset(msg.width, msg.height, 0);
    for (size_t i = 0; i < n; ++i) labels->data[i] = GetU16(raw + 2 * i);
  };
  switch (msg.compression) {
    case clutterseg::label_image_t::COMPRESSION_NONE:
      from_raw(msg.data.data(), msg.data.size());
      return;
    case clutterseg::label_image_t::COMPRESSION_RLE: {
      if (msg.data.size() % 6 != 0) {
        throw std::runtime_error("label_image_t: RLE data is truncated");
      }
      // The runs must cover the image exactly (each at least one pixel) before it is filled.
      uint64_t covered = 0;
      for (size_t i = 0; i < msg.data.size(); i += 6) {
        const uint32_t run = GetU32(&msg.data[i + 2]);
        if (run == 0) throw std::runtime_error("label_image_t: RLE run of length 0");
        if (run > n - covered) throw std::runtime_error("label_image_t: RLE runs exceed the image");
        covered += run;
      }
      if (covered != n) throw std::runtime_error("label_image_t: RLE runs do not cover the image");
      labels->Reset(msg.width, msg.height, 0);
      size_t pos = 0;
      for (size_t i = 0; i < msg.data.size(); i += 6) {
        const uint16_t v = GetU16(&msg.data[i]);
        const uint32_t run = GetU32(&msg.data[i + 2]);
        std::fill_n(labels->data.begin() + static_cast<std::ptrdiff_t>(pos), run, uint32_t{v});
        pos += run;
      }
      return;
    }
    case clutterseg::label_image_t::COMPRESSION_ZLIB: {
      // Deflate expands by at most 1032:1: a short stream cannot hold a large image.
      if (2 * static_cast<uint64_t>(n) > 1032 * static_cast<uint64_t>(msg.data.size()) + 1024) {
        throw std::runtime_error("label_image_t: " + std::to_string(msg.data.size()) +
                                 " zlib bytes cannot hold " + std::to_string(n) + " labels");
      }
      std::vector<uint8_t> raw(2 * n);
      uLongf size = static_cast<uLongf>(raw.size());
      if (uncompress(raw.data(), &size, msg.data.data(), static_cast<uLong>(msg.data.size())) !=
          Z_OK) {
        throw std::runtime_error("label_image_t: corrupt zlib data");
      }
      from_raw(raw.data(), size);
      return;
    }
    default:
      throw std::runtime_error("label_image_t: unknown compression " +
                               std::to_string(static_cast<int>(msg.compression)));
  }
}

}  // namespace clutterseg::daemon
