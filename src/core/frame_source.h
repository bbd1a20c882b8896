#pragma once

#include <string>

#include "clutterseg/core/frame.h"
#include "clutterseg/core/source_report.h"

namespace clutterseg::core {

/// Result of one FrameSource::Read.
enum class ReadStatus {
  kOk,            ///< `frame` holds a new frame
  kTimeout,       ///< nothing arrived within the timeout; try again
  kEndOfStream,   ///< a recording or directory is exhausted (not looping)
  kDisconnected,  ///< a live device went away; Close() and Open() again to reconnect
  kError,         ///< unrecoverable; last_error() says why
};

/// Where frames come from: a live camera, an .oni recording, a directory of PCD / PNG files
/// or the synthetic scene generator. Implementations live in drivers/ and know their
/// hardware or format; the pipeline only sees this interface.
///
/// Thread-safety: a source is used by one capture thread at a time, except RequestStop(),
/// which may be called from any thread to make a blocking Read return promptly, and report(),
/// which may be called from any thread at any time.
///
/// Frames a source holds but cannot deliver (a truncated file in a directory, a damaged frame
/// of a recording, a frame beyond core::FrameLimits) are skipped: Read() goes on with the next
/// frame and counts the skipped one, with its reason, in report(). Read() returns kError only
/// when the source as a whole cannot go on.
class FrameSource {
 public:
  virtual ~FrameSource() = default;

  /// Opens the device or file. @throws std::runtime_error with a clear message (naming the
  /// file, URI or serial) when it cannot be opened.
  virtual void Open() = 0;
  /// Waits at most `timeout_ms` for the next frame and fills `frame`, reusing its buffers.
  /// Never throws for expected conditions (end of file, device loss): returns a status.
  virtual ReadStatus Read(int timeout_ms, RgbdFrame* frame) = 0;
  /// Releases the device or file. Safe to call more than once.
  virtual void Close() = 0;
  /// True for a live camera (frames arrive at the sensor's pace and are dropped when late),
  /// false for recordings read in lockstep.
  virtual bool IsLive() const = 0;
  /// One line for logs, e.g. "oni:/data/run1.oni (640x480 depth+color, 300 frames)".
  virtual std::string Describe() const = 0;
  /// Why the last Read returned kError or kDisconnected.
  virtual std::string last_error() const = 0;
  /// Asks a blocking Read to return (kTimeout or kEndOfStream) as soon as possible.
  virtual void RequestStop() {}
  /// What the source delivered and what it could not (skipped frames with their reasons,
  /// frames without any measurement or without colour), counted since construction; see
  /// SourceReport. At kEndOfStream of a finite source every frame is accounted for:
  /// `frames_delivered + frames_skipped() == frames_in_source` (per pass). Consumers should
  /// treat `lost_frames()` and `all_empty()` as a failed run. Sources that count nothing
  /// return the default report (frames_in_source -1, all counts 0).
  /// Thread-safe: any thread, also while another thread is inside Read(); O(recent skips).
  virtual SourceReport report() const { return {}; }
};

}  // namespace clutterseg::core
