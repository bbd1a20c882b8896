#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

namespace clutterseg::core {

/// Why a source could not deliver a frame it holds.
enum class SkipReason {
  kUnreadable,    ///< the file or frame could not be read or decoded (truncated, corrupt, I/O)
  kTooLarge,      ///< it declares a size beyond core::FrameLimits
  kSizeMismatch,  ///< its size disagrees with the stream's or the recording's (short payload)
  kNotDelivered,  ///< the recording holds it, but it never arrived (a damaged frame record, or
                  ///< a player that ended early)
};
inline constexpr size_t kNumSkipReasons = 4;

/// Stable lower-case name of a reason for logs and messages: "unreadable", "too_large",
/// "size_mismatch", "not_delivered".
const char* ToString(SkipReason reason);

/// One frame (or `count` frames for the same cause) a source skipped.
struct SkippedFrame {
  /// Number of the (last) frame of this entry among all frames the source skipped since it
  /// was constructed: 1 for the first, 2 for the next...
  uint64_t serial{0};
  uint64_t count{1};  ///< frames this entry stands for
  SkipReason reason{SkipReason::kUnreadable};
  std::string what;  ///< names the file or frame and the problem
};

/// What a core::FrameSource delivered and what it could not, counted since the source was
/// constructed (over every Open(), every loop of a recording and every reconnect).
///
/// For a finite source (a recording or a directory, not looping) that reached kEndOfStream,
/// every frame is accounted for: `frames_delivered + frames_skipped() == frames_in_source`.
/// A looping source adds `frames_in_source` per completed pass (`passes_completed`).
struct SourceReport {
  /// Frames one pass over the recording or directory holds (depth frames for a recording);
  /// -1 when unknown (a live camera) or before the first Open().
  int64_t frames_in_source{-1};
  uint64_t passes_completed{0};  ///< passes that reached the end of the recording / directory
  uint64_t frames_delivered{0};  ///< frames Read() returned with kOk
  /// Delivered frames without a single measurement: every depth pixel 0 and no finite cloud
  /// point. A few are normal (a covered lens); all of them means the data or its
  /// configuration (depth scale, intrinsics) is wrong. See all_empty().
  uint64_t frames_empty{0};
  /// Delivered frames without colour although the source has a colour stream: no colour
  /// frame matched the depth frame (ids and timestamps apart), or the colour was unusable.
  uint64_t frames_without_color{0};
  /// Colour frames dropped because no depth frame matched them (or they were unusable).
  uint64_t color_frames_unmatched{0};
  /// Frames not delivered, by SkipReason (index = static_cast<size_t>(reason)).
  std::array<uint64_t, kNumSkipReasons> skipped{};
  /// The most recent skipped frames, oldest first, at most kMaxRecentSkips; `serial` numbers
  /// them, so a consumer that polls can print each one once.
  std::vector<SkippedFrame> recent_skips;

  static constexpr size_t kMaxRecentSkips = 32;

  /// Frames not delivered, all reasons together.
  uint64_t frames_skipped() const;
  uint64_t skipped_for(SkipReason reason) const { return skipped[static_cast<size_t>(reason)]; }
  /// True when some frame the source holds was not delivered.
  bool lost_frames() const { return frames_skipped() > 0; }
  /// True when at least one frame was delivered and every delivered frame was empty.
  bool all_empty() const { return frames_delivered > 0 && frames_empty == frames_delivered; }
  /// One line, e.g. "7 of 8 frames delivered, 1 skipped (1 not_delivered), 0 empty; last
  /// skipped: rec.oni: ...".
  std::string ToString() const;
};

/// The counters behind FrameSource::report(), for implementations: the capture thread counts,
/// any thread takes a Snapshot(). One short critical section per call; Delivered() does not
/// allocate.
///
/// Thread-safety: every method may be called from any thread.
class SourceCounters {
 public:
  SourceCounters() = default;
  SourceCounters(const SourceCounters&) = delete;
  SourceCounters& operator=(const SourceCounters&) = delete;

  /// Sets the frames one pass holds (-1 = unknown).
  void SetFramesInSource(int64_t frames);
  /// Counts a delivered frame; `empty` and `without_color` as in SourceReport.
  void Delivered(bool empty, bool without_color = false);
  /// Counts `count` frames skipped for `reason`; `what` names the file or frame and the
  /// problem (kept for the most recent skips).
  void Skipped(SkipReason reason, std::string what, uint64_t count = 1);
  void ColorUnmatched(uint64_t count = 1);
  void PassCompleted();
  SourceReport Snapshot() const;

 private:
  mutable std::mutex mutex_;
  SourceReport report_;
  uint64_t serial_{0};
};

}  // namespace clutterseg::core
