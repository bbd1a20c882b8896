#pragma once

#include <memory>
#include <string>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/frame_limits.h"
#include "clutterseg/core/frame_source.h"
#include "clutterseg/drivers/openni2/openni2_library.h"

namespace clutterseg::drivers {

/// Options of OpenNI2Source. Plain values; see ValidateOrThrow() for the accepted ranges.
struct OpenNI2SourceOptions {
  /// "" = the first device found, a device URI (as listed by OpenNI2), or a path to an .oni
  /// recording (any existing file, or a name ending in ".oni").
  std::string uri;
  /// Open the live device with this serial number (ignored for files; exclusive with `uri`).
  std::string serial;
  /// Also stream colour (RGB888). Recordings without a colour stream give depth only.
  bool color{true};
  /// Register depth to colour on the device (IMAGE_REGISTRATION_DEPTH_TO_COLOR) when the
  /// device supports it. Recordings cannot be registered at replay: store registered depth.
  bool registration{true};
  int width{640};  ///< live capture resolution, px
  int height{480};
  int fps{30};  ///< live capture rate, frames per second
  /// Replay speed: 1.0 = the recorded rate, 2.0 = twice as fast, -1 = lockstep (as fast as
  /// the consumer reads, never dropping a frame). 0 (free running, drops frames) is refused.
  double replay_speed{1.0};
  bool loop{false};  ///< restart a recording at its end instead of returning kEndOfStream
  std::string camera_name{"camera"};  ///< copied into RgbdFrame::camera_name
  /// Largest frame accepted: a recording whose streams declare more is refused at Open(), a
  /// delivered frame beyond them is skipped (SkipReason::kTooLarge).
  core::FrameLimits limits;

  /// @throws std::invalid_argument naming the key and value when an option is out of range.
  void ValidateOrThrow() const;
};

/// Loads libOpenNI2 and initializes OpenNI2 once per process; later calls do nothing (the
/// first call's `drivers` stays in force: with kRecordingsOnly no camera can be opened in this
/// process). Thread-safe. Call it from main() before starting other threads:
/// OpenNI::initialize() temporarily chdir()s the whole process into the OpenNI2 drivers
/// directory, which breaks relative paths used concurrently by other threads.
/// OpenNI2Source::Open() calls it with kAll (harmless once done).
/// @throws std::runtime_error when libOpenNI2 cannot be loaded or initialized, with
/// OpenNI2's extended error.
void InitializeOpenNI2(OpenNI2Drivers drivers = OpenNI2Drivers::kAll);

/// Where libOpenNI2 was loaded from and which drivers it sees, for logs: e.g.
/// "/usr/lib/x86_64-linux-gnu/libOpenNI2.so.0 (all drivers)"; "" before InitializeOpenNI2().
std::string DescribeOpenNI2();

/// Shuts OpenNI2 down if InitializeOpenNI2() succeeded. Call once, at process exit, after
/// every OpenNI2Source has been closed. Thread-safe.
void ShutdownOpenNI2();

/// A core::FrameSource over OpenNI2: a live PrimeSense-class camera (Xtion, Kinect 1,
/// Carmine) or the replay of an .oni recording through OpenNI2's OniFile driver.
///
/// Frames carry depth in millimetres (DEPTH_1_MM; DEPTH_100_UM is converted), colour RGB888
/// when enabled and of the depth's size, the device timestamp in microseconds as `utime`,
/// and intrinsics derived from the stream's field of view: fx = W / (2 tan(hfov / 2)),
/// fy = H / (2 tan(vfov / 2)), cx = W / 2 - 0.5, cy = H / 2 - 0.5 (pixel-centre convention;
/// OpenNI2's own converter uses W / 2, half a pixel away). The intrinsics are checked with
/// core::CameraIntrinsics::ValidateOrThrow (a field of view of 10..150 degrees): a recording
/// or device reporting another is refused at Open() with a message naming it and the value.
/// When the device or recording reports no field of view at all, the Kinect defaults scaled
/// to the resolution are used (Describe() says so).
///
/// Depth drives the frames: every depth frame is delivered, and the colour frame whose
/// timestamp is within half a frame period of it is attached (frame ids are not used: each
/// stream numbers its own frames, and a dropped colour frame shifts them). Depth whose colour
/// is missing or late is delivered alone (counted in SourceReport::frames_without_color),
/// colour that matches no depth is dropped (SourceReport::color_frames_unmatched). This holds
/// for live cameras and recordings alike, whatever the ids or the order of the records (a
/// recording's colour is read through a second lockstep player of the same file, so the
/// order of its records does not matter).
///
/// Replay: the file is validated with OniReader before OpenNI2 sees it: unfinalized,
/// truncated or garbage files, streams larger than `limits`, an implausible field of view, a
/// required frame size smaller than the image, and NONE-coded frames whose size disagrees
/// with the declared image size make Open() throw with a message naming the file (nothing
/// garbled is replayed). OpenNI2's player always runs in lockstep (it never drops a frame);
/// a speed > 0 is applied by pacing the frames on their recorded timestamps. The file is
/// never seek()ed (the Debian build crashes on seek). Every wait is bounded, so a Read never
/// blocks for longer than its timeout; the end of a recording gives kEndOfStream. report()
/// holds the recording's depth frame count (read with OniReader) and accounts for each one:
/// delivered, or skipped with a reason (a delivered frame larger than `limits` or shorter
/// than its image; frames a damaged recording declares but does not hold, or that OpenNI2
/// never delivered: kNotDelivered).
///
/// Live: a device that goes away makes Read return kDisconnected; Close() and Open() again to
/// reconnect. Frames beyond `limits` or shorter than their image are skipped and counted.
///
/// Thread-safety: as core::FrameSource (one capture thread; RequestStop from any thread).
/// OpenNI2 listener callbacks only set atomic flags and never throw.
class OpenNI2Source final : public core::FrameSource {
 public:
  /// @throws std::invalid_argument when `options` are invalid.
  explicit OpenNI2Source(const OpenNI2SourceOptions& options);
  ~OpenNI2Source() override;
  OpenNI2Source(const OpenNI2Source&) = delete;
  OpenNI2Source& operator=(const OpenNI2Source&) = delete;

  void Open() override;
  core::ReadStatus Read(int timeout_ms, core::RgbdFrame* frame) override;
  void Close() override;
  /// True for a live camera and for recordings replayed at a real-time speed (> 0), where the
  /// player drops frames the consumer misses; false for lockstep replay (speed -1).
  bool IsLive() const override;
  std::string Describe() const override;
  std::string last_error() const override;
  void RequestStop() override;
  /// See core::FrameSource::report(); frames_in_source is the recording's depth frame count
  /// (-1 for a live device). Thread-safe.
  core::SourceReport report() const override;

  /// True after Open() of a recording.
  bool is_file() const;
  /// Depth frames the recording holds (after Open() of a file), -1 for a live device.
  int number_of_frames() const;
  /// Intrinsics of the depth stream (valid after Open()).
  core::CameraIntrinsics intrinsics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace clutterseg::drivers
