#pragma once

// Constants of the ONI container ("NI10", version 1.0.1.0) shared by OniWriter and OniReader.
// All integers are little-endian and every structure is packed.

#include <cstdint>

namespace clutterseg::drivers::internal {

inline constexpr char kOniMagic[4] = {'N', 'I', '1', '0'};
inline constexpr uint32_t kOniRecordMagic = 0x0052494E;  // "NIR\0"
inline constexpr uint32_t kOniFileHeaderSize = 24;
inline constexpr uint32_t kOniRecordHeaderSize = 28;     // version >= 1.0.1.0
inline constexpr uint32_t kOniOldRecordHeaderSize = 24;  // versions 1.0.0.4 .. 1.0.0.x
inline constexpr uint32_t kOniSeekEntrySize = 20;        // u64 ts, u32 config, u64 offset

enum class OniRecordType : uint32_t {
  kNodeAdded1004 = 0x02,
  kIntProperty = 0x03,
  kRealProperty = 0x04,
  kStringProperty = 0x05,
  kGeneralProperty = 0x06,
  kNodeRemoved = 0x07,
  kNodeDataBegin = 0x08,
  kNodeStateReady = 0x09,
  kNewData = 0x0A,
  kEnd = 0x0B,
  kNodeAdded1005 = 0x0C,
  kNodeAdded = 0x0D,
  kSeekTable = 0x0E,
};

enum class OniNodeType : uint32_t {
  kDevice = 1,
  kDepth = 2,
  kImage = 3,
  kIr = 5,
};

/// OniPixelFormat values used in `oniPixelFormat`.
inline constexpr uint64_t kOniPixelFormatDepth1Mm = 100;
inline constexpr uint64_t kOniPixelFormatDepth100Um = 101;
inline constexpr uint64_t kOniPixelFormatRgb888 = 200;
inline constexpr uint64_t kOniPixelFormatGray16 = 203;

}  // namespace clutterseg::drivers::internal
