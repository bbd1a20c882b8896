#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/synth/renderer.h"
#include "clutterseg/synth/scene.h"
#include "clutterseg/synth/sensor_params.h"
#include "test_scenes.h"

namespace clutterseg::synth {
namespace {

using testing::CameraFrameScene;
using testing::FrontalWall;
using testing::MakePrimitive;

constexpr double kPi = 3.14159265358979323846;

// Depth errors (metres, measured minus true) of the valid pixels in the central 200 x 200.
void AppendCentralErrors(const RenderedFrame& f, std::vector<double>* errors) {
  for (int v = f.depth.height / 2 - 100; v < f.depth.height / 2 + 100; ++v) {
    for (int u = f.depth.width / 2 - 100; u < f.depth.width / 2 + 100; ++u) {
      const uint16_t d = f.depth.at(u, v);
      if (d != 0) errors->push_back(d * 0.001 - f.true_depth_m.at(u, v));
    }
  }
}

// Sample correlation of the depth error between pixels `d` apart along rows, over the valid
// pixel pairs of the whole image.
double ErrorCorrelation(const RenderedFrame& f, int d) {
  double sxy = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, syy = 0.0;
  long n = 0;
  for (int v = 0; v < f.depth.height; ++v) {
    for (int u = 0; u + d < f.depth.width; ++u) {
      const uint16_t a = f.depth.at(u, v);
      const uint16_t b = f.depth.at(u + d, v);
      if (a == 0 || b == 0) continue;
      const double x = a * 0.001 - f.true_depth_m.at(u, v);
      const double y = b * 0.001 - f.true_depth_m.at(u + d, v);
      sxy += x * y;
      sx += x;
      sy += y;
      sxx += x * x;
      syy += y * y;
      ++n;
    }
  }
  const double cov = sxy / n - (sx / n) * (sy / n);
  return cov / std::sqrt((sxx / n - (sx / n) * (sx / n)) * (syy / n - (sy / n) * (sy / n)));
}

// Fraction of horizontally adjacent valid pixel pairs that report the same depth.
double EqualNeighbourFraction(const RenderedFrame& f) {
  long equal = 0, pairs = 0;
  for (int v = 0; v < f.depth.height; ++v) {
    for (int u = 0; u + 1 < f.depth.width; ++u) {
      const uint16_t a = f.depth.at(u, v);
      const uint16_t b = f.depth.at(u + 1, v);
      if (a == 0 || b == 0) continue;
      equal += a == b ? 1 : 0;
      ++pairs;
    }
  }
  return static_cast<double>(equal) / pairs;
}

TEST(SensorModel, AxialNoiseOnFlatWallHasConfiguredSigma) {
  const SensorParams sensor;  // default: correlated noise and 1/8 px disparity quantisation on
  for (double z : {1.0, 2.0}) {
    Scene scene = CameraFrameScene();
    scene.primitives.push_back(FrontalWall(z));
    // The noise is correlated over several pixels, so one image holds few independent
    // samples: pool the per-pixel errors of several noise seeds.
    std::vector<double> errors;
    RenderedFrame frame;
    for (uint64_t seed = 17; seed < 17 + 8; ++seed) {
      RenderScene(scene, core::DefaultKinectIntrinsics(), sensor, seed, &frame);
      AppendCentralErrors(frame, &errors);
    }
    ASSERT_GT(errors.size(), 8u * 39000u);
    double sum = 0.0, sum2 = 0.0;
    for (double e : errors) {
      sum += e;
      sum2 += e * e;
    }
    const double bias = sum / errors.size();
    const double sigma = std::sqrt(std::max(0.0, sum2 / errors.size() - bias * bias));
    const double expected = sensor.AxialSigmaM(z);
    RecordProperty(z < 1.5 ? "sigma_1m_um" : "sigma_2m_um", static_cast<int>(sigma * 1e6));
    EXPECT_NEAR(sigma, expected, 0.2 * expected) << "z = " << z;
    EXPECT_NEAR(bias, 0.0, 0.5 * expected) << "z = " << z;
  }
  // The model itself: 0.0012 + 0.0019 (z - 0.4)^2.
  EXPECT_NEAR(sensor.AxialSigmaM(1.0), 0.0012 + 0.0019 * 0.36, 1e-12);
}

TEST(SensorModel, AxialNoiseIsSpatiallyCorrelatedAndDecaysWithDistance) {
  Scene scene = CameraFrameScene();
  scene.primitives.push_back(FrontalWall(1.5));
  SensorParams sensor = NoiselessSensorParams();
  sensor.axial_noise = true;  // no quantisation, lateral noise or dropout
  ASSERT_GT(sensor.axial_noise_correlation_px, 2.0);
  RenderedFrame frame;
  RenderScene(scene, core::DefaultKinectIntrinsics(), sensor, 5, &frame);
  double previous = 1.0;
  for (int d : {1, 2, 4, 8, 16}) {
    const double rho = ErrorCorrelation(frame, d);
    EXPECT_LT(rho, previous) << "d = " << d;
    RecordProperty("rho_" + std::to_string(d) + "px_x100", static_cast<int>(100 * rho));
    previous = rho;
    if (d == 1) {
      EXPECT_GT(rho, 0.85);
    }
  }
  EXPECT_LT(previous, 0.15);  // 16 px apart: nearly independent

  // Correlation length 0: independent per-pixel noise.
  sensor.axial_noise_correlation_px = 0.0;
  RenderScene(scene, core::DefaultKinectIntrinsics(), sensor, 5, &frame);
  EXPECT_NEAR(ErrorCorrelation(frame, 1), 0.0, 0.05);
  // A longer correlation length correlates distant pixels more.
  sensor.axial_noise_correlation_px = 20.0;
  RenderScene(scene, core::DefaultKinectIntrinsics(), sensor, 5, &frame);
  EXPECT_GT(ErrorCorrelation(frame, 8), 0.6);
}

TEST(SensorModel, CorrelationLengthIsValidated) {
  SensorParams sensor;
  sensor.axial_noise_correlation_px = -1.0;
  try {
    sensor.ValidateOrThrow();
    ADD_FAILURE() << "negative correlation length accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axial_noise_correlation_px"), std::string::npos);
  }
  sensor.axial_noise_correlation_px = 0.0;
  EXPECT_NO_THROW(sensor.ValidateOrThrow());
}

TEST(SensorModel, CorrelatedNoiseQuantisesIntoTerraces) {
  // A flat wall at 1 m: the 1/8 px disparity step is 2.9 mm, the noise sigma 1.9 mm.
  Scene scene = CameraFrameScene();
  scene.primitives.push_back(FrontalWall(1.0));
  SensorParams sensor;
  sensor.lateral_sigma_px = 0.0;
  RenderedFrame frame;
  RenderScene(scene, core::DefaultKinectIntrinsics(), sensor, 9, &frame);
  const double correlated = EqualNeighbourFraction(frame);
  sensor.axial_noise_correlation_px = 0.0;
  RenderScene(scene, core::DefaultKinectIntrinsics(), sensor, 9, &frame);
  const double independent = EqualNeighbourFraction(frame);
  RecordProperty("equal_neighbours_pct", static_cast<int>(100 * correlated));
  EXPECT_GT(correlated, 0.85);
  EXPECT_LT(independent, 0.6);
}

TEST(SensorModel, QuantisationAloneProducesDisparitySteps) {
  SensorParams sensor = NoiselessSensorParams();
  sensor.disparity_step_px = 0.125;
  Scene scene = CameraFrameScene();
  // A wall tilted about the vertical axis: depth varies smoothly across the image.
  Primitive wall = FrontalWall(2.0);
  const double a = 30.0 * kPi / 180.0;
  wall.pose = Pose::FromAxes({std::cos(a), 0.0, -std::sin(a)}, {0.0, 1.0, 0.0},
                             {std::sin(a), 0.0, std::cos(a)}, {0.0, 0.0, 2.0});
  scene.primitives.push_back(wall);
  RenderedFrame frame;
  RenderScene(scene, core::DefaultKinectIntrinsics(), sensor, 1, &frame);
  const double fb = sensor.disparity_focal_px * sensor.baseline_m;
  int checked = 0;
  for (int u = 0; u < frame.depth.width; u += 3) {
    const uint16_t mm = frame.depth.at(u, 240);
    if (mm == 0) continue;
    // Every measured depth is fb / (k / 8) for an integer k (up to the mm rounding).
    const double disparity = fb / (mm * 0.001);
    const double k = std::round(disparity / 0.125);
    EXPECT_NEAR(fb / (k * 0.125), mm * 0.001, 0.0006) << u;
    ++checked;
  }
  EXPECT_GT(checked, 150);
}

TEST(SensorModel, ShadowFallsBesideTheBoxAwayFromTheProjector) {
  // Box (front face at 1.1 m) in front of a wall at 2 m; projector at +x (image right).
  Scene scene = CameraFrameScene();
  scene.primitives.push_back(FrontalWall(2.0));
  scene.primitives.push_back(
      MakePrimitive(PrimitiveKind::kBox, {0.0, 0.0, 1.2}, {0.3, 0.3, 0.2}, 1));
  SensorParams sensor = NoiselessSensorParams();
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, sensor, 1, &frame);
  const int v = static_cast<int>(k.cy);
  const int box_left = static_cast<int>(std::ceil(k.cx - k.fx * 0.15 / 1.1));
  const int box_right = static_cast<int>(std::floor(k.cx + k.fx * 0.15 / 1.1));
  int shadow_left = 0, shadow_right = 0;
  for (int u = 0; u < k.width; ++u) {
    if (frame.status.at(u, v) != static_cast<uint8_t>(DepthStatus::kShadow)) continue;
    EXPECT_EQ(frame.depth.at(u, v), 0);
    EXPECT_EQ(frame.label.at(u, v), 0u);
    if (u < box_left) ++shadow_left;
    if (u > box_right) ++shadow_right;
  }
  // Width of the band: f b (1/z_box - 1/z_wall) pixels.
  const double expected = k.fx * sensor.baseline_m * (1.0 / 1.1 - 1.0 / 2.0);
  EXPECT_NEAR(shadow_left, expected, 1.5);
  EXPECT_EQ(shadow_right, 0);
  // With shadows disabled the band is measured.
  sensor.projector_shadows = false;
  RenderScene(scene, k, sensor, 1, &frame);
  for (int u = 0; u < k.width; ++u) EXPECT_GT(frame.depth.at(u, v), 0) << u;
}

TEST(SensorModel, GrazingSurfacesAreInvalid) {
  // A floor 0.3 m below the camera (y down): incidence grows towards the horizon.
  Scene scene = CameraFrameScene();
  Primitive floor = FrontalWall(0.0);
  floor.pose = Pose::FromAxes({1.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, {0.0, -1.0, 0.0}, {0.0, 0.3, 0.0});
  scene.primitives.push_back(floor);
  SensorParams sensor = NoiselessSensorParams();
  sensor.max_range_m = 60.0;
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, sensor, 1, &frame);
  int grazing = 0, valid = 0;
  for (int v = static_cast<int>(k.cy) + 1; v < k.height; ++v) {
    for (int u = 0; u < k.width; u += 4) {
      const Vec3 d{(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0};
      const double incidence = std::acos(d.y / Norm(d)) * 180.0 / kPi;
      const double depth = 0.3 / d.y;
      if (depth < sensor.min_range_m || depth > sensor.max_range_m) continue;
      if (std::abs(incidence - sensor.max_incidence_deg) < 0.05) continue;
      const auto status = static_cast<DepthStatus>(frame.status.at(u, v));
      if (incidence > sensor.max_incidence_deg) {
        ASSERT_EQ(status, DepthStatus::kGrazing) << u << "," << v;
        ASSERT_EQ(frame.depth.at(u, v), 0);
        ++grazing;
      } else {
        ASSERT_EQ(status, DepthStatus::kValid) << u << "," << v;
        ++valid;
      }
    }
  }
  EXPECT_GT(grazing, 1000);
  EXPECT_GT(valid, 1000);
}

TEST(SensorModel, RangeLimitsAndDropout) {
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  Scene near = CameraFrameScene();
  near.primitives.push_back(FrontalWall(0.35));
  RenderScene(near, k, SensorParams{}, 1, &frame);
  for (uint16_t d : frame.depth.data) ASSERT_EQ(d, 0);
  Scene far = CameraFrameScene();
  far.primitives.push_back(FrontalWall(4.6));
  RenderScene(far, k, SensorParams{}, 1, &frame);
  for (uint16_t d : frame.depth.data) ASSERT_EQ(d, 0);

  // Random dropout removes about the configured fraction of a flat wall.
  SensorParams sensor = NoiselessSensorParams();
  sensor.dropout_fraction = 0.05;
  Scene wall = CameraFrameScene();
  wall.primitives.push_back(FrontalWall(1.5));
  RenderScene(wall, k, sensor, 3, &frame);
  int dropped = 0;
  for (uint8_t s : frame.status.data) dropped += s == static_cast<uint8_t>(DepthStatus::kDropout);
  EXPECT_NEAR(dropped / static_cast<double>(frame.status.size()), 0.05, 0.005);
}

TEST(SensorModel, EdgeDropoutOnlyNearDepthDiscontinuities) {
  Scene scene = CameraFrameScene();
  scene.primitives.push_back(FrontalWall(2.0));
  scene.primitives.push_back(
      MakePrimitive(PrimitiveKind::kBox, {0.0, 0.0, 1.2}, {0.3, 0.3, 0.2}, 1));
  SensorParams sensor = IdealSensorParams();
  sensor.edge_dropout_probability = 1.0;
  const core::CameraIntrinsics k = core::DefaultKinectIntrinsics();
  RenderedFrame frame;
  RenderScene(scene, k, sensor, 1, &frame);
  int dropped = 0;
  for (int v = 1; v + 1 < k.height; ++v) {
    for (int u = 1; u + 1 < k.width; ++u) {
      if (frame.status.at(u, v) != static_cast<uint8_t>(DepthStatus::kDropout)) continue;
      ++dropped;
      float zmin = 1e9f, zmax = 0.f;
      for (int dv = -1; dv <= 1; ++dv) {
        for (int du = -1; du <= 1; ++du) {
          zmin = std::min(zmin, frame.true_depth_m.at(u + du, v + dv));
          zmax = std::max(zmax, frame.true_depth_m.at(u + du, v + dv));
        }
      }
      ASSERT_GT(zmax - zmin, 0.5f) << u << "," << v;
    }
  }
  // The box outline (about 4 x 143 px) is dropped on both sides of the edge.
  EXPECT_GT(dropped, 4 * 140);
}

}  // namespace
}  // namespace clutterseg::synth
