#pragma once

namespace clutterseg::synth {

/// A structured-light depth sensor model (Kinect v1 / Xtion class). The projector sits
/// `baseline_m` along the camera's +x axis (to the right in the image). Depth noise is applied
/// in disparity space: d = disparity_focal_px * baseline_m / z, perturbed by Gaussian noise
/// whose depth-equivalent sigma together with the disparity quantisation gives the axial
/// sigma(z) = axial_sigma_base_m + axial_sigma_quad_m * (z - axial_sigma_offset_m)^2
/// (Nguyen, Izadi, Lovell 2012). The noise is spatially correlated (see
/// axial_noise_correlation_px) and added before the quantisation, so flat surfaces show
/// quantisation terraces rather than per-pixel salt.
struct SensorParams {
  double baseline_m{0.075};
  double disparity_focal_px{580.0};
  /// Disparity quantisation step (pixels); 0 disables quantisation.
  double disparity_step_px{0.125};

  /// Axial (depth) noise on/off; when on, sigma(z) as above is the total depth sigma.
  bool axial_noise{true};
  double axial_sigma_base_m{0.0012};
  double axial_sigma_quad_m{0.0019};
  double axial_sigma_offset_m{0.4};
  /// Correlation length (pixels) of the axial noise: the disparity noise is a smooth random
  /// field whose correlation between pixels d apart is about exp(-(d / length)^2), as block
  /// matching over a window correlates neighbouring pixels; each pixel's sigma is unchanged.
  /// 0 gives independent per-pixel noise.
  double axial_noise_correlation_px{7.0};

  /// Lateral noise: each pixel reports the surface seen from a neighbour offset by a
  /// rounded Gaussian of this sigma (pixels); 0 disables.
  double lateral_sigma_px{0.3};

  /// Pixels whose surface point the projector cannot see are invalid.
  bool projector_shadows{true};
  /// Pixels whose incidence angle (camera ray vs surface normal) exceeds this are invalid.
  double max_incidence_deg{78.0};
  double min_range_m{0.4};
  double max_range_m{4.5};

  /// Fraction of valid pixels dropped independently.
  double dropout_fraction{0.002};
  /// Pixels within one pixel of a depth discontinuity are dropped in square clusters of
  /// `edge_cluster_px` with this probability.
  double edge_dropout_probability{0.25};
  int edge_cluster_px{2};
  /// A neighbour is across a discontinuity when its depth differs by more than this
  /// fraction of the pixel's depth.
  double edge_jump_fraction{0.03};

  /// Per-channel Gaussian noise of the colour image (8-bit units); 0 disables.
  double color_noise_sigma{2.0};

  /// Total axial depth sigma in metres at depth `z_m` (the Nguyen model).
  double AxialSigmaM(double z_m) const {
    const double dz = z_m - axial_sigma_offset_m;
    return axial_sigma_base_m + axial_sigma_quad_m * dz * dz;
  }

  /// @throws std::invalid_argument naming the key and value when a field is out of range.
  void ValidateOrThrow() const;
};

/// Noise-free sensor: exact depths (up to the millimetre of the output format), no shadows,
/// no grazing limit, no dropout; only the range limits remain.
SensorParams IdealSensorParams();

/// The default sensor with every random effect and the disparity quantisation off; the
/// geometric effects (projector shadows, grazing angles, range limits) stay on.
SensorParams NoiselessSensorParams();

}  // namespace clutterseg::synth
