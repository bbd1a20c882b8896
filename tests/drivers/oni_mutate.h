#pragma once

// Byte-level edits of ONI recordings written by our OniWriter, for the replay fault tests:
// the record layout is walked here independently of drivers::OniReader (24-byte file header,
// 28-byte record headers: magic, type, node id, fieldsSize, payloadSize, undo position).

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace clutterseg::drivers::testutil {

inline constexpr uint32_t kRecIntProperty = 0x03;
inline constexpr uint32_t kRecGeneralProperty = 0x06;
inline constexpr uint32_t kRecNewData = 0x0A;
inline constexpr uint32_t kRecSeekTable = 0x0E;

inline std::vector<uint8_t> ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void WriteFileBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

inline uint64_t GetLe(const std::vector<uint8_t>& b, size_t at, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v |= uint64_t{b[at + static_cast<size_t>(i)]} << (8 * i);
  return v;
}

inline void PutLe(std::vector<uint8_t>* b, size_t at, uint64_t v, int n) {
  for (int i = 0; i < n; ++i)
    (*b)[at + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}

struct OniRecord {
  size_t offset{0};
  uint32_t type{0};
  uint32_t node{0};
  uint32_t fields_size{0};
  uint32_t payload_size{0};
  std::string name;  // property name for property records
  size_t size() const { return size_t{fields_size} + payload_size; }
};

inline std::vector<OniRecord> WalkOni(const std::vector<uint8_t>& b) {
  std::vector<OniRecord> out;
  size_t pos = 24;
  while (pos + 28 <= b.size() && GetLe(b, pos, 4) == 0x0052494Eu) {
    OniRecord r;
    r.offset = pos;
    r.type = static_cast<uint32_t>(GetLe(b, pos + 4, 4));
    r.node = static_cast<uint32_t>(GetLe(b, pos + 8, 4));
    r.fields_size = static_cast<uint32_t>(GetLe(b, pos + 12, 4));
    r.payload_size = static_cast<uint32_t>(GetLe(b, pos + 16, 4));
    if (r.type >= 0x03 && r.type <= 0x06) {
      const auto len = static_cast<size_t>(GetLe(b, pos + 28, 4));
      r.name.assign(reinterpret_cast<const char*>(b.data() + pos + 32), len > 0 ? len - 1 : 0);
    }
    out.push_back(r);
    if (r.type == 0x0B) break;  // END
    pos += r.size();
  }
  return out;
}

/// Offset of the value of property `name` of `node` (the bytes after its data size).
inline size_t PropertyValueOffset(const std::vector<uint8_t>& b, uint32_t node,
                                  const std::string& name) {
  for (const OniRecord& r : WalkOni(b)) {
    if (r.node == node && r.name == name) return r.offset + 28 + 4 + name.size() + 1 + 4;
  }
  return 0;
}

/// The NEW_DATA records of `node`, in file order.
inline std::vector<OniRecord> FrameRecordsOf(const std::vector<uint8_t>& b, uint32_t node) {
  std::vector<OniRecord> frames;
  for (const OniRecord& r : WalkOni(b)) {
    if (r.type == kRecNewData && r.node == node) frames.push_back(r);
  }
  return frames;
}

inline void SetFrameId(std::vector<uint8_t>* b, const OniRecord& frame, uint32_t id) {
  PutLe(b, frame.offset + 28 + 8, id, 4);
}

inline void SetFrameTimestamp(std::vector<uint8_t>* b, const OniRecord& frame, uint64_t ts) {
  PutLe(b, frame.offset + 28, ts, 8);
}

/// Rewrites the frame records so that all of node 1's (depth) come before node 2's (colour),
/// keeping every record's bytes, and updates the seek tables to the new offsets.
inline void DepthRecordsFirst(std::vector<uint8_t>* b) {
  const std::vector<OniRecord> records = WalkOni(*b);
  size_t begin = 0;
  size_t end = 0;
  std::vector<OniRecord> depth;
  std::vector<OniRecord> color;
  for (const OniRecord& r : records) {
    if (r.type != kRecNewData) continue;
    if (begin == 0) begin = r.offset;
    end = r.offset + r.size();
    (r.node == 1 ? depth : color).push_back(r);
  }
  std::vector<uint8_t> region;
  std::vector<size_t> depth_at;
  std::vector<size_t> color_at;
  for (const OniRecord& r : depth) {
    depth_at.push_back(begin + region.size());
    region.insert(region.end(), b->begin() + static_cast<std::ptrdiff_t>(r.offset),
                  b->begin() + static_cast<std::ptrdiff_t>(r.offset + r.size()));
  }
  for (const OniRecord& r : color) {
    color_at.push_back(begin + region.size());
    region.insert(region.end(), b->begin() + static_cast<std::ptrdiff_t>(r.offset),
                  b->begin() + static_cast<std::ptrdiff_t>(r.offset + r.size()));
  }
  std::memcpy(b->data() + begin, region.data(), end - begin);
  // Undo positions: the previous record of the same node.
  for (size_t i = 0; i < depth_at.size(); ++i)
    PutLe(b, depth_at[i] + 20, i ? depth_at[i - 1] : 0, 8);
  for (size_t i = 0; i < color_at.size(); ++i)
    PutLe(b, color_at[i] + 20, i ? color_at[i - 1] : 0, 8);
  for (const OniRecord& r : WalkOni(*b)) {
    if (r.type != kRecSeekTable) continue;
    const std::vector<size_t>& at = r.node == 1 ? depth_at : color_at;
    for (size_t i = 0; i < at.size(); ++i)
      PutLe(b, r.offset + r.fields_size + 20 * (i + 1) + 12, at[i], 8);
  }
}

}  // namespace clutterseg::drivers::testutil
