#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "clutterseg/core/types.h"

namespace clutterseg::pipeline {

/// The temporal depth filter of a camera's frame stream (docs/method.md, "Temporal
/// coherence"). YAML section `segmenter.temporal`. The defaults come from the structured-light
/// sensor model of src/synth (synth::SensorParams: axial sigma(z) = 1.2 mm + 1.9 mm
/// (z - 0.4 m)^2, 1.9 mm at 1 m): the band is 3.75 sigmas, chosen on the tuning pile sequences
/// among 1.6-4.8 sigmas (docs/results.md, "Temporal coherence").
struct TemporalFilterParams {
  static constexpr std::string_view kSection = "segmenter.temporal";

  /// Filter the frames of a stream (a camera, an .oni recording, the synthetic source). Never
  /// applied to single files or directories of files (clutterseg-segment, PCD or depth-PNG
  /// directories): their frames need not show one scene.
  bool enabled{true};
  /// A pixel averages at most this many frames (its running mean weighs the newest frame
  /// 1 / min(n, max_frames)); 1 = no averaging. Frames, not time.
  int max_frames{30};
  /// A new depth that differs from the pixel's mean by more than the band resets the pixel to
  /// it (a change, shown at once); within the band it is averaged in. Band at 1 m depth,
  /// metres; it scales with depth squared like the sensor's noise...
  float band_at_1m_m{0.007f};
  /// ...and is never below this, metres (the sensor's noise floor near the camera).
  float min_band_m{0.0045f};
  /// A pixel without a measurement (depth 0) shows its mean for up to this many frames in a
  /// row before it is a hole (0 = a hole is always a hole). Its mean is kept either way, so a
  /// measurement after a dropout that lies within the band continues the average.
  int hole_fill_frames{0};

  /// The band at depth `z_m` (metres): max(min_band_m, band_at_1m_m * z_m^2), metres.
  float BandAt(float z_m) const { return std::max(min_band_m, band_at_1m_m * z_m * z_m); }

  /// @throws std::invalid_argument naming the key (`segmenter.temporal.<field>`) and value.
  void ValidateOrThrow() const;
  bool operator==(const TemporalFilterParams&) const = default;
};

/// Averages each pixel's depth over the frames in which it stays within the sensor's noise
/// band, and resets a pixel at once to the new depth where it leaves the band. Whatever moves
/// by more than the band (an object put down, removed or pushed, an arm entering) therefore
/// shows in the filtered depth of the very frame in which it is measured: the worst-case delay
/// is 0 frames, and every filtered depth lies within the band of the frame's own measurement.
///
/// State per pixel: the running mean (float, millimetres), the number of frames in it (uint8)
/// and the frames since the last measurement (uint8): 6 bytes, 1.8 MB for 640 x 480
/// (memory_bytes()). It lives until the pixel changes, the image size changes or Reset().
///
/// Frames must be given in capture order, one stream per filter. The output depends only on
/// the frames given and their order (no threads, no clock).
///
/// Thread-safety: not reentrant; one thread at a time. Cost: one pass over the pixels, no
/// allocation after the first frame of a size.
class TemporalDepthFilter {
 public:
  /// @throws std::invalid_argument when `params` fail validation.
  explicit TemporalDepthFilter(const TemporalFilterParams& params);

  /// Filters `depth` (millimetres, 0 = no measurement) in place and updates the state. A
  /// frame of another size than the previous one starts afresh.
  void Apply(core::DepthImage* depth);
  /// Forgets every pixel's history: the next frame passes unchanged.
  void Reset();

  /// Pixels of the last Apply that were reset by a change (a first frame counts every
  /// measured pixel).
  size_t num_reset() const { return num_reset_; }
  /// Bytes of state kept (for the frame size seen last).
  size_t memory_bytes() const;
  const TemporalFilterParams& params() const { return params_; }

 private:
  const TemporalFilterParams params_;
  int width_{0};
  int height_{0};
  std::vector<float> mean_mm_;    // running mean, mm; 0 = no history
  std::vector<uint8_t> count_;    // frames in the mean (1..max_frames), 0 = none
  std::vector<uint8_t> missing_;  // frames in a row without a measurement
  size_t num_reset_{0};
};

}  // namespace clutterseg::pipeline
