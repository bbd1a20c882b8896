#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/types.h"

namespace clutterseg::drivers {

/// Largest frame payload OpenNI2's OniFile player buffers (1600x1200 RGB888): OniWriter never
/// writes larger frames and OniReader refuses them by default.
inline constexpr uint32_t kOniFileMaxFrameBytes = 1600u * 1200u * 3u;

/// Limits that protect OniReader against hostile files. Every size read from a file is
/// checked against the file size and these limits before anything is allocated.
struct OniReadLimits {
  /// The frame limits every reader and writer shares: the resolution a node declares in
  /// xnMapOutputMode must fit them as an image (checked with 1 byte per pixel; the payload
  /// limit below is stricter).
  core::FrameLimits frame;
  uint32_t max_fields_bytes{1u << 20};              ///< largest record header + fields
  uint32_t max_string_bytes{4096};                  ///< longest node or property name
  size_t max_nodes{64};                             ///< most nodes in one file
  uint32_t max_frame_bytes{kOniFileMaxFrameBytes};  ///< largest frame payload (OniFile's)
  /// Most frame records indexed (about 9 hours of depth and colour at 30 fps): the index
  /// costs 48 bytes per record.
  size_t max_frame_records{size_t{1} << 21};
};

/// One node (stream) declared by NODE_ADDED, with the properties OpenNI2 replays.
struct OniNodeInfo {
  uint32_t id{0};
  std::string name;              ///< "Depth", "Image", "IR", ...
  uint32_t type{0};              ///< 1 device, 2 depth, 3 image, 5 IR
  std::string codec;             ///< four characters: "NONE", "16zT", "JPEG", ...
  uint32_t number_of_frames{0};  ///< as declared in NODE_ADDED (0xFFFFFFFF: never finalized)
  uint64_t min_timestamp_us{0};
  uint64_t max_timestamp_us{0};
  uint64_t seek_table_offset{0};  ///< 0 = none
  uint64_t node_added_offset{0};
  int width{0};  ///< from xnMapOutputMode, 0 when absent
  int height{0};
  int fps{0};
  int64_t pixel_format{-1};  ///< oniPixelFormat, -1 when absent
  double hfov_rad{0.0};      ///< from xnFOV, 0 when absent
  double vfov_rad{0.0};
  bool has_cropping{false};  ///< xnCropping present (OniFile delivers no frames without it)
  bool state_ready{false};   ///< NODE_STATE_READY seen
  bool data_begin{false};    ///< NODE_DATA_BEGIN seen
  bool removed{false};       ///< NODE_REMOVED seen
  /// Entries in the node's SEEK_TABLE payload (read at seek_table_offset when the walk did
  /// not reach it), 0 when there is none or it is damaged.
  uint32_t seek_table_entries{0};
  uint32_t data_records{0};  ///< NEW_DATA records seen
  std::map<std::string, int64_t> int_properties;
  std::map<std::string, double> real_properties;
  std::map<std::string, std::string> string_properties;
  std::map<std::string, std::vector<uint8_t>> general_properties;
};

/// One NEW_DATA record.
struct OniFrameRecord {
  size_t node_index{0};  ///< index into OniFileInfo::nodes
  uint64_t timestamp_us{0};
  uint32_t frame_id{0};  ///< 1-based
  uint64_t record_offset{0};
  uint64_t payload_offset{0};
  uint32_t payload_bytes{0};
};

/// Everything OniReader learnt from walking the records of a file.
struct OniFileInfo {
  int version_major{0};
  int version_minor{0};
  int version_maintenance{0};
  int version_build{0};
  uint64_t global_max_timestamp{0};
  uint32_t max_node_id{0};
  std::vector<OniNodeInfo> nodes;
  std::vector<OniFrameRecord> frames;  ///< in file order, all nodes interleaved
  size_t record_count{0};
  /// Records of a type this reader (and OpenNI2) does not know, skipped: a damaged file.
  /// OpenNI2's player also loses the frame record that follows each of them.
  size_t unknown_records{0};
  bool has_end{false};  ///< an END record was found (a finalized file)

  /// The first node of `type` (2 depth, 3 image), or nullptr.
  const OniNodeInfo* FindNode(uint32_t type) const;
  /// Index of the first node of `type`, or -1.
  int FindNodeIndex(uint32_t type) const;
};

/// Walks an in-memory ONI file (versions 1.0.0.4 .. 1.0.1.0) and returns its records.
/// @throws std::runtime_error naming `name` and the offset for anything malformed: bad magic
/// or version, truncated records, sizes beyond the file or `limits`, unknown nodes, frame ids
/// or timestamps the header forbids. Never reads outside [data, data + size).
OniFileInfo ParseOni(const uint8_t* data, size_t size, const std::string& name,
                     const OniReadLimits& limits = {});

/// A small, independent reader of ONI files, for tests, tools and fuzzing (no OpenNI2).
/// Only the NONE codec can be decoded; other codecs (16zT, JPEG) are listed but refused when
/// their frames are read. Thread-safety: none.
class OniReader {
 public:
  OniReader();
  ~OniReader();
  OniReader(const OniReader&) = delete;
  OniReader& operator=(const OniReader&) = delete;

  /// Opens `path` and indexes all its records (payloads are not read).
  /// @throws std::runtime_error naming the file when it cannot be read or is malformed.
  void Open(const std::string& path, const OniReadLimits& limits = {});
  void Close();
  const OniFileInfo& info() const;

  /// Reads frame `index` (into info().frames) of a depth node (16-bit, codec NONE).
  /// @throws std::runtime_error naming the file for another codec or a size mismatch.
  void ReadDepth(size_t index, core::DepthImage* depth);
  /// Reads frame `index` of an RGB888 image node (codec NONE). @throws std::runtime_error.
  void ReadColor(size_t index, core::ColorImage* color);
  /// Reads the raw payload of frame `index`. @throws std::runtime_error on I/O failure.
  void ReadPayload(size_t index, std::vector<uint8_t>* payload);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::drivers
