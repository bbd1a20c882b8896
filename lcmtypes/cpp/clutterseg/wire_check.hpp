#pragma once

// Bounds checks of clutterseg's LCM messages before they are decoded. lcm-gen's decoders size
// every array from the count in the message before they look at what follows, so a corrupt or
// hostile objects_t that claims 2^29 objects makes decode() allocate gigabytes; and some
// malformed strings make them throw std::length_error. These walks verify that every string
// and array a message declares fits in its bytes, field by field, and cost a fraction of the
// decode. Header-only, shipped with the generated C++ bindings; clutterseg-listen and
// clutterseg-regress check every message with them.
//
//   #include "clutterseg/wire_check.hpp"
//   // data, size: the message as received, with its 8-byte type hash
//   if (size >= 8 && clutterseg::wire::CheckObjects(data + 8, size - 8).empty()) {
//     msg.decode(data, 0, static_cast<int>(size));
//   }
//
// Keep the walks in step with lcmtypes/clutterseg/*.lcm (tests/daemon/label_bounds_test.cc
// publishes every type with all its arrays filled and fails when a walk rejects it).
// Thread-safety: the functions are reentrant.

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>

namespace clutterseg::wire {

// A bounds check of LCM's wire format (big-endian; a nested struct carries no hash) that
// walks a message and verifies that every string and array it declares fits in the bytes
// that follow, before lcm-gen's decode allocates them. Trailing bytes are allowed.
class WireCheck {
 public:
  WireCheck(const uint8_t* data, size_t size) : data_(data), size_(size) {}

  bool Skip(size_t n, const char* what) {
    if (!ok_) return false;
    if (n > size_ - pos_) return Bad(std::string(what) + " runs past the end of the message");
    pos_ += n;
    return true;
  }
  bool Int32(int32_t* value, const char* what) {
    if (!Skip(4, what)) return false;
    const uint8_t* p = data_ + pos_ - 4;
    *value = static_cast<int32_t>((uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) |
                                  (uint32_t{p[2]} << 8) | uint32_t{p[3]});
    return true;
  }
  bool String(const char* what) {
    int32_t len = 0;
    if (!Int32(&len, what)) return false;
    if (len < 1) return Bad(std::string(what) + " has length " + std::to_string(len));
    return Skip(static_cast<size_t>(len), what);
  }
  // A count of elements of at least `min_bytes` each that must fit in what is left.
  bool Count(int32_t* count, size_t min_bytes, const char* what) {
    if (!Int32(count, what)) return false;
    if (*count < 0 || static_cast<uint64_t>(*count) * min_bytes > size_ - pos_) {
      return Bad(std::string(what) + " = " + std::to_string(*count) + " does not fit in the " +
                 std::to_string(size_ - pos_) + " bytes left");
    }
    return true;
  }
  bool Strings(int32_t count, const char* what) {
    for (int32_t i = 0; i < count; ++i) {
      if (!String(what)) return false;
    }
    return ok_;
  }
  const std::string& problem() const { return problem_; }

 private:
  bool Bad(std::string why) {
    if (ok_) problem_ = std::move(why);
    ok_ = false;
    return false;
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_{0};
  bool ok_{true};
  std::string problem_;
};

// The walks below follow lcmtypes/clutterseg/*.lcm field by field; keep them in step with
// the types (tests/daemon/label_bounds_test.cc publishes every type with all its arrays
// filled and fails when a walk rejects a well-formed message).
// Encoded sizes of the fixed-size structs and parts.
inline constexpr size_t kIntrinsicsBytes = 4 + 4 + 4 * 8;
inline constexpr size_t kPlaneBytes = 4 + 3 * 4 + 4 + 4 + 1;
// object_t up to num_samples: geometry, support, gravity box, colour, confidence, image box,
// track.
inline constexpr size_t kObjectFixedBytes = 4 + 4 + 4 * 3 * 4 + 9 * 4 + 3 * 4 + 4 +
                                            (1 + 3 * 4 + 9 * 4 + 3 * 4 + 4 + 4) + 3 + 4 + 4 * 4 +
                                            8 + 4 + 4 + 1 + 1;
inline constexpr size_t kLostTrackBytes = 8 + 4 + 4 + 4 + 1 + 4 + 5 * 3 * 4;

// stage_times_t: num_stages, stage_names[], stage_ms[], total_ms.
inline bool CheckStageTimes(WireCheck* w) {
  int32_t n = 0;
  return w->Count(&n, 5 + 4, "times.num_stages") && w->Strings(n, "times.stage_names") &&
         w->Skip(static_cast<size_t>(n) * 4 + 4, "times.stage_ms");
}

/// The objects_t payload after its type hash: "" when it is safe to decode, else why not.
inline std::string CheckObjects(const uint8_t* data, size_t size) {
  WireCheck w(data, size);
  int32_t n = 0;
  int32_t objects = 0;
  if (w.Skip(8 + 8 + 8, "utime, device_utime and frame_seq") && w.String("camera_name") &&
      w.Skip(kIntrinsicsBytes, "intrinsics") && w.String("frame_id") &&
      w.Skip(3 * 8 + 4 * 8, "camera pose") && w.Count(&n, kPlaneBytes, "num_planes") &&
      w.Skip(static_cast<size_t>(n) * kPlaneBytes, "planes") &&
      w.Count(&objects, kObjectFixedBytes + 4, "num_objects")) {
    for (int32_t i = 0; i < objects; ++i) {
      if (!w.Skip(kObjectFixedBytes, "object") || !w.Count(&n, 12, "object.num_samples") ||
          !w.Skip(static_cast<size_t>(n) * 12, "object.samples")) {
        break;
      }
    }
  }
  w.Count(&n, kLostTrackBytes, "num_lost_tracks") &&
      w.Skip(static_cast<size_t>(n) * kLostTrackBytes, "lost_tracks") &&
      w.Count(&n, 8, "num_ended_tracks") && w.Skip(static_cast<size_t>(n) * 8, "ended_track_ids") &&
      w.Skip(1 + 4 + 4, "tracks_reset and counts") && CheckStageTimes(&w) &&
      w.Skip(4 + 4 + 4, "times");
  return w.problem();
}

/// The label_image_t payload after its type hash; as CheckObjects.
inline std::string CheckLabels(const uint8_t* data, size_t size) {
  WireCheck w(data, size);
  int32_t n = 0;
  w.Skip(8 + 8 + 8, "utime, device_utime and frame_seq") && w.String("camera_name") &&
      w.Skip(4 + 4 + 1, "size") && w.Count(&n, 1, "size") && w.Skip(static_cast<size_t>(n), "data");
  return w.problem();
}

/// The status_t payload after its type hash; as CheckObjects.
inline std::string CheckStatus(const uint8_t* data, size_t size) {
  WireCheck w(data, size);
  int32_t n = 0;
  w.Skip(8, "utime") && w.String("camera_name") && w.String("source") && w.String("version") &&
      w.Skip(8, "instance_id") && w.String("hostname") && w.Skip(4, "pid") &&
      w.Skip(8 * 4, "rates") && w.Count(&n, 5 + 4 + 4, "num_stages") &&
      w.Strings(n, "stage_names") &&
      w.Skip(static_cast<size_t>(n) * 8 + 4 + 4 + 13 * 8 + 4 + 1, "counters") &&
      w.String("device_state_name") && w.Skip(4, "reconnect_attempts") && w.String("last_error");
  return w.problem();
}

}  // namespace clutterseg::wire
