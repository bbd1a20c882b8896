#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/frame_source.h"
#include "clutterseg/core/types.h"
#include "clutterseg/synth/scene.h"
#include "clutterseg/synth/sensor_params.h"

namespace clutterseg::drivers {

/// Options of SyntheticSource.
struct SyntheticSourceOptions {
  uint64_t seed{1};
  /// Frames before the end (or before looping).
  int num_frames{30};
  /// true: one incremental sequence (synth::GenerateSequence: empty table, then one more
  /// object per frame, fixed camera); false: an independent scene per frame
  /// (synth::GenerateScene with seed + k).
  bool incremental{true};
  bool loop{false};  ///< restart at frame 0 (the same scenes and noise) after the last frame
  /// Sleep so that frames are delivered at the frame rate, like a live camera.
  bool real_time{false};
  int64_t frame_period_us{33333};  ///< frame k has utime = k * frame_period_us (k counts loops)
  synth::SceneParams scene;
  synth::SensorParams sensor;
  core::CameraIntrinsics intrinsics{core::DefaultKinectIntrinsics()};
  int render_threads{1};  ///< threads used to render (the output does not depend on it)
  std::string camera_name{"synthetic"};

  /// @throws std::invalid_argument naming the key and value when an option is out of range.
  void ValidateOrThrow() const;
};

/// A core::FrameSource rendering synthetic labelled tabletop scenes (src/synth) with a
/// structured-light sensor model. Deterministic: the same options give the same frames.
/// The ground-truth label image of the last frame is available through last_labels().
/// Thread-safety: as core::FrameSource.
class SyntheticSource final : public core::FrameSource {
 public:
  /// @throws std::invalid_argument when `options` are invalid.
  explicit SyntheticSource(const SyntheticSourceOptions& options);
  ~SyntheticSource() override;
  SyntheticSource(const SyntheticSource&) = delete;
  SyntheticSource& operator=(const SyntheticSource&) = delete;

  /// Generates the scenes. @throws std::runtime_error when scene generation fails.
  void Open() override;
  core::ReadStatus Read(int timeout_ms, core::RgbdFrame* frame) override;
  void Close() override;
  bool IsLive() const override { return options_.real_time; }
  std::string Describe() const override;
  std::string last_error() const override { return error_; }
  void RequestStop() override;
  /// See core::FrameSource::report(); frames_in_source is `num_frames`.
  core::SourceReport report() const override;

  /// Object labels of the last frame read (0 = background or no depth), pixel-aligned.
  const core::LabelImage& last_labels() const;

 private:
  struct Impl;
  const SyntheticSourceOptions options_;
  std::unique_ptr<Impl> impl_;
  std::string error_;
};

}  // namespace clutterseg::drivers
