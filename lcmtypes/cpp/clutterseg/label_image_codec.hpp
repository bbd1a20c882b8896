#pragma once

// Encoding and decoding of clutterseg::label_image_t payloads: the per-pixel object ids of
// one frame, row-major (pixel (u, v) at index v * width + u), 0 = background or no
// measurement. Header-only, shipped with the generated C++ bindings (target
// clutterseg::lcmtypes, which links zlib); the daemon publishes with the same code.
//
//   #include "clutterseg/label_image_codec.hpp"
//   std::vector<uint16_t> ids;
//   std::string error;
//   if (!clutterseg::DecodeLabelImage(msg, &ids, &error)) { /* malformed: error says why */ }
//
// Thread-safety: the functions are reentrant.

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/label_image_t.hpp"

namespace clutterseg {

/// Images above this many pixels are refused by the decoder (the daemon's frame limit).
inline constexpr int64_t kMaxLabelImagePixels = int64_t{4096} * 4096;

namespace label_codec_internal {
inline void PutLe16(uint16_t v, uint8_t* p) {
  p[0] = static_cast<uint8_t>(v & 0xff);
  p[1] = static_cast<uint8_t>(v >> 8);
}
inline uint16_t GetLe16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
inline uint32_t GetLe32(const uint8_t* p) {
  return uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24);
}
inline bool Fail(std::string* error, const std::string& why) {
  if (error != nullptr) *error = "label_image_t: " + why;
  return false;
}
}  // namespace label_codec_internal

/// Fills msg->compression, msg->data and msg->size from `ids` (width * height ids, row-major)
/// with `compression` (label_image_t::COMPRESSION_*), reusing msg->data's storage. `scratch`
/// (may be null) holds the uncompressed layout for zlib. Returns false (with `error`) for a
/// size mismatch, an unknown compression or a zlib failure.
template <typename Id>
bool EncodeLabelImage(const Id* ids, int32_t width, int32_t height, int8_t compression,
                      label_image_t* msg, std::vector<uint8_t>* scratch = nullptr,
                      std::string* error = nullptr) {
  using namespace label_codec_internal;
  if (width < 0 || height < 0 || int64_t{width} * height > kMaxLabelImagePixels) {
    return Fail(error, "bad size " + std::to_string(width) + "x" + std::to_string(height));
  }
  const size_t n = static_cast<size_t>(width) * static_cast<size_t>(height);
  auto clamp = [](Id v) {
    return static_cast<uint16_t>(std::min<uint64_t>(static_cast<uint64_t>(v), 65535u));
  };
  msg->width = width;
  msg->height = height;
  msg->compression = compression;
  std::vector<uint8_t>& data = msg->data;
  std::vector<uint8_t> local;
  std::vector<uint8_t>& raw = scratch != nullptr ? *scratch : local;
  auto to_raw = [&](std::vector<uint8_t>* out) {
    out->resize(2 * n);
    uint8_t* p = out->data();
    for (size_t i = 0; i < n; ++i, p += 2) PutLe16(clamp(ids[i]), p);
  };
  switch (compression) {
    case label_image_t::COMPRESSION_NONE:
      to_raw(&data);
      break;
    case label_image_t::COMPRESSION_RLE: {
      data.clear();
      size_t i = 0;
      while (i < n) {
        const Id raw = ids[i];
        const uint16_t v = clamp(raw);
        const size_t limit = n - i > UINT32_MAX ? i + UINT32_MAX : n;
        size_t j = i + 1;
        for (;;) {
          // Equal ids four at a time (one branch per four), then one at a time; an id that
          // differs but clamps to the same value continues the run.
          while (j + 4 <= limit && ((ids[j] ^ raw) | (ids[j + 1] ^ raw) | (ids[j + 2] ^ raw) |
                                    (ids[j + 3] ^ raw)) == 0) {
            j += 4;
          }
          while (j < limit && ids[j] == raw) ++j;
          if (j < limit && clamp(ids[j]) == v) {
            ++j;
            continue;
          }
          break;
        }
        const uint32_t run = static_cast<uint32_t>(j - i);
        const uint8_t pair[6] = {static_cast<uint8_t>(v & 0xff),   static_cast<uint8_t>(v >> 8),
                                 static_cast<uint8_t>(run & 0xff), static_cast<uint8_t>(run >> 8),
                                 static_cast<uint8_t>(run >> 16),  static_cast<uint8_t>(run >> 24)};
        data.insert(data.end(), pair, pair + 6);
        i = j;
      }
      break;
    }
    case label_image_t::COMPRESSION_ZLIB: {
      to_raw(&raw);
      uLongf size = compressBound(static_cast<uLong>(raw.size()));
      data.resize(size);
      if (compress2(data.data(), &size, raw.data(), static_cast<uLong>(raw.size()), 1) != Z_OK) {
        return Fail(error, "zlib compress2 failed");
      }
      data.resize(size);
      break;
    }
    default:
      return Fail(error, "unknown compression " + std::to_string(compression));
  }
  msg->size = static_cast<int32_t>(data.size());
  return true;
}

/// Decodes `msg` into `ids` (resized to width * height, row-major). Returns false, with
/// `error` naming the problem and `ids` left empty, for a malformed message: a size outside
/// 0..kMaxLabelImagePixels, a size field that disagrees with the data, runs or inflated
/// bytes that do not exactly cover the image, an unknown compression. Nothing is allocated
/// beyond the image the header declares.
template <typename Id>
bool DecodeLabelImage(const label_image_t& msg, std::vector<Id>* ids,
                      std::string* error = nullptr) {
  using namespace label_codec_internal;
  ids->clear();
  if (msg.width < 0 || msg.height < 0 || int64_t{msg.width} * msg.height > kMaxLabelImagePixels) {
    return Fail(error, "bad size " + std::to_string(msg.width) + "x" + std::to_string(msg.height));
  }
  if (msg.size < 0 || static_cast<size_t>(msg.size) != msg.data.size()) {
    return Fail(error, "size field " + std::to_string(msg.size) + " != data length " +
                           std::to_string(msg.data.size()));
  }
  const size_t n = static_cast<size_t>(msg.width) * static_cast<size_t>(msg.height);
  const uint8_t* data = msg.data.data();
  const size_t bytes = msg.data.size();
  switch (msg.compression) {
    case label_image_t::COMPRESSION_NONE:
      if (bytes != 2 * n) {
        return Fail(error,
                    std::to_string(bytes) + " label bytes for " + std::to_string(n) + " pixels");
      }
      ids->resize(n);
      for (size_t i = 0; i < n; ++i) (*ids)[i] = static_cast<Id>(GetLe16(data + 2 * i));
      return true;
    case label_image_t::COMPRESSION_RLE: {
      if (bytes % 6 != 0) return Fail(error, "RLE data is truncated");
      // The runs must cover the image exactly: checked before the image is allocated.
      uint64_t covered = 0;
      for (size_t i = 0; i < bytes; i += 6) {
        covered += GetLe32(data + i + 2);
        if (covered > n) return Fail(error, "RLE runs exceed the image");
      }
      if (covered != n) {
        return Fail(error, "RLE runs cover " + std::to_string(covered) + " of " +
                               std::to_string(n) + " pixels");
      }
      ids->resize(n);
      size_t pos = 0;
      for (size_t i = 0; i < bytes; i += 6) {
        const uint32_t run = GetLe32(data + i + 2);
        std::fill_n(ids->begin() + static_cast<std::ptrdiff_t>(pos), run,
                    static_cast<Id>(GetLe16(data + i)));
        pos += run;
      }
      return true;
    }
    case label_image_t::COMPRESSION_ZLIB: {
      std::vector<uint8_t> raw(2 * n);
      uLongf size = static_cast<uLongf>(raw.size());
      // uncompress stops at the image's size: a zlib bomb fails with Z_BUF_ERROR.
      const int rc = uncompress(raw.data(), &size, data, static_cast<uLong>(bytes));
      if (rc != Z_OK || size != raw.size()) {
        return Fail(error, rc == Z_BUF_ERROR ? "zlib data larger than the image"
                                             : "zlib data does not inflate to the image");
      }
      ids->resize(n);
      for (size_t i = 0; i < n; ++i) (*ids)[i] = static_cast<Id>(GetLe16(raw.data() + 2 * i));
      return true;
    }
    default:
      return Fail(error, "unknown compression " + std::to_string(msg.compression));
  }
}

}  // namespace clutterseg
