#include "clutterseg/synth/internal/noise_field.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "clutterseg/core/thread_pool.h"

namespace clutterseg::synth::internal {
namespace {

struct Moments {
  double mean{0.0};
  double variance{0.0};
};

Moments ComputeMoments(const std::vector<float>& f) {
  double s = 0.0, s2 = 0.0;
  for (float x : f) {
    s += x;
    s2 += static_cast<double>(x) * x;
  }
  Moments m;
  m.mean = s / f.size();
  m.variance = s2 / f.size() - m.mean * m.mean;
  return m;
}

// Sample correlation between pixels `d` apart horizontally and vertically.
double Correlation(const std::vector<float>& f, int w, int h, int d) {
  double sxy = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, syy = 0.0;
  long n = 0;
  auto add = [&](double x, double y) {
    sxy += x * y;
    sx += x;
    sy += y;
    sxx += x * x;
    syy += y * y;
    ++n;
  };
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u + d < w; ++u) add(f[v * w + u], f[v * w + u + d]);
  }
  for (int v = 0; v + d < h; ++v) {
    for (int u = 0; u < w; ++u) add(f[v * w + u], f[(v + d) * w + u]);
  }
  const double cov = sxy / n - (sx / n) * (sy / n);
  return cov / std::sqrt((sxx / n - (sx / n) * (sx / n)) * (syy / n - (sy / n) * (sy / n)));
}

TEST(CorrelatedGaussianField, UnitVarianceForEveryCorrelationLength) {
  const int w = 640, h = 480;
  std::vector<float> field;
  for (double length : {0.0, 1.5, 3.0, 8.0, 20.0}) {
    // Pool several seeds: a long correlation leaves few independent samples per image.
    double mean = 0.0, var = 0.0;
    const int seeds = length > 10.0 ? 12 : 3;
    for (int s = 0; s < seeds; ++s) {
      CorrelatedGaussianField(100 + s, w, h, length, &field);
      ASSERT_EQ(field.size(), static_cast<size_t>(w * h));
      const Moments m = ComputeMoments(field);
      mean += m.mean / seeds;
      var += (m.variance + m.mean * m.mean) / seeds;
    }
    EXPECT_NEAR(var, 1.0, 0.1) << "length " << length;
    EXPECT_NEAR(mean, 0.0, 0.15) << "length " << length;
  }
}

TEST(CorrelatedGaussianField, VarianceIsTheSameBetweenAndOnGridNodes) {
  // Correlation 12 px puts grid nodes every 4 px. Pixels midway between nodes would have about
  // 0.9 of the nodes' variance without the interpolation correction.
  const int w = 64, h = 64;
  std::vector<float> field;
  double on_node = 0.0, between = 0.0;
  int n = 0;
  for (uint64_t seed = 0; seed < 1000; ++seed) {
    CorrelatedGaussianField(seed, w, h, 12.0, &field);
    for (int v = 0; v + 2 < h; v += 4) {
      for (int u = 0; u + 2 < w; u += 4) {
        on_node += field[v * w + u] * field[v * w + u];
        between += field[(v + 2) * w + u + 2] * field[(v + 2) * w + u + 2];
        ++n;
      }
    }
  }
  EXPECT_NEAR(on_node / n, 1.0, 0.04);
  EXPECT_NEAR(between / n, 1.0, 0.04);
}

TEST(CorrelatedGaussianField, CorrelationFollowsTheLengthAndDecays) {
  const int w = 640, h = 480;
  std::vector<float> field;
  CorrelatedGaussianField(7, w, h, 0.0, &field);
  EXPECT_NEAR(Correlation(field, w, h, 1), 0.0, 0.02);
  for (double length : {4.0, 8.0, 16.0}) {
    CorrelatedGaussianField(7, w, h, length, &field);
    double previous = 1.0;
    for (int d : {1, 2, 4, 8, 16, 32, 64}) {
      const double rho = Correlation(field, w, h, d);
      const double expected = std::exp(-(d / length) * (d / length));
      // Sampling error grows with the correlation length (fewer independent samples).
      EXPECT_NEAR(rho, expected, 0.06 + 0.004 * length) << "length " << length << " d " << d;
      if (d <= length) {
        EXPECT_LT(rho, previous) << "length " << length << " d " << d;
      }
      previous = rho;
    }
    EXPECT_GT(Correlation(field, w, h, 1), 0.9) << length;
  }
}

TEST(CorrelatedGaussianField, DeterministicBySeedForAnyThreadCount) {
  std::vector<float> a, b, c;
  core::ThreadPool pool(3);
  for (double length : {0.0, 2.0, 12.0}) {
    CorrelatedGaussianField(42, 333, 211, length, &a);
    CorrelatedGaussianField(42, 333, 211, length, &b, &pool);
    CorrelatedGaussianField(43, 333, 211, length, &c, &pool);
    EXPECT_EQ(a, b) << length;
    EXPECT_NE(a, c) << length;
  }
}

}  // namespace
}  // namespace clutterseg::synth::internal
