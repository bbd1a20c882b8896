#include "clutterseg/synth/internal/noise_field.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include "clutterseg/core/assert.h"
#include "clutterseg/synth/random.h"

namespace clutterseg::synth::internal {
namespace {

// Rows per ParallelFor chunk (fixed, so chunking never depends on the thread count).
constexpr size_t kRowGrain = 16;

void ParallelRows(core::ThreadPool* pool, size_t rows, const std::function<void(size_t)>& fn) {
  auto run = [&](size_t b, size_t e) {
    for (size_t r = b; r < e; ++r) fn(r);
  };
  if (pool == nullptr) {
    run(0, rows);
  } else {
    pool->ParallelFor(rows, kRowGrain, run);
  }
}

uint64_t CellBits(uint64_t seed, uint64_t index) {
  return Mix64(seed + index * 0x9e3779b97f4a7c15ULL);
}

// A standard normal variate for pixel `index` of an uncorrelated field with mixed seed `seed`.
double CellGaussian(uint64_t seed, uint64_t index) {
  const uint64_t h = CellBits(seed, index);
  return GaussianFromBits(Mix64(h ^ 0x243f6a8885a308d3ULL), Mix64(h ^ 0x13198a2e03707344ULL));
}

// A unit-variance variate for grid cell `index` of a smoothed field: the kernel sums at least
// 7 x 7 of them, so their sum is Gaussian even though each one is bounded (Irwin-Hall).
double CellVariate(uint64_t seed, uint64_t index) {
  return FastGaussianFromBits(CellBits(seed, index));
}

// Bilinear interpolation of one axis: for each pixel coordinate, the lower grid node, the
// fractional offset and 1 / sqrt of the variance factor (1-a)^2 + a^2 + 2 a (1-a) rho1 of a
// unit-variance field whose neighbouring nodes correlate by rho1.
struct AxisMap {
  std::vector<int> node;
  std::vector<float> frac;
  std::vector<float> inv_sd;
};

AxisMap MakeAxisMap(int pixels, int spacing, double rho1) {
  AxisMap m;
  m.node.resize(static_cast<size_t>(pixels));
  m.frac.resize(static_cast<size_t>(pixels));
  m.inv_sd.resize(static_cast<size_t>(pixels));
  for (int p = 0; p < pixels; ++p) {
    const double a = static_cast<double>(p % spacing) / spacing;
    const double var = (1.0 - a) * (1.0 - a) + a * a + 2.0 * a * (1.0 - a) * rho1;
    m.node[static_cast<size_t>(p)] = p / spacing;
    m.frac[static_cast<size_t>(p)] = static_cast<float>(a);
    m.inv_sd[static_cast<size_t>(p)] = static_cast<float>(1.0 / std::sqrt(var));
  }
  return m;
}

}  // namespace

void CorrelatedGaussianField(uint64_t seed, int width, int height, double correlation_px,
                             std::vector<float>* out, core::ThreadPool* pool) {
  CLUTTERSEG_DEMAND(out != nullptr && width > 0 && height > 0);
  const size_t w = static_cast<size_t>(width);
  const size_t h = static_cast<size_t>(height);
  const uint64_t mixed = Mix64(seed ^ 0xa4093822299f31d0ULL);
  out->resize(w * h);
  if (!(correlation_px > 0.0)) {
    ParallelRows(pool, h, [&](size_t v) {
      for (size_t u = 0; u < w; ++u)
        (*out)[v * w + u] = static_cast<float>(CellGaussian(mixed, v * w + u));
    });
    return;
  }

  // Smoothing white noise with a Gaussian kernel of standard deviation s gives the
  // correlation exp(-d^2 / (4 s^2)), so s = correlation_px / 2 (in pixels). The kernel runs on
  // a grid `spacing` pixels apart, where its standard deviation is 1.5..3 cells.
  const double sigma_px = 0.5 * correlation_px;
  const int spacing = std::max(1, static_cast<int>(std::floor(sigma_px / 1.5)));
  const double sigma_cells = sigma_px / spacing;
  const int radius = static_cast<int>(std::ceil(3.0 * sigma_cells));
  std::vector<double> kernel(static_cast<size_t>(2 * radius + 1));
  double sum_sq = 0.0;
  for (int j = -radius; j <= radius; ++j) {
    const double k = std::exp(-0.5 * j * j / (sigma_cells * sigma_cells));
    kernel[static_cast<size_t>(j + radius)] = k;
    sum_sq += k * k;
  }
  // Unit sum of squares per axis: unit variance at every grid node.
  for (double& k : kernel) k /= std::sqrt(sum_sq);
  double rho1 = 0.0;  // correlation of neighbouring grid nodes along one axis
  for (size_t j = 0; j + 1 < kernel.size(); ++j) rho1 += kernel[j] * kernel[j + 1];

  // Grid nodes cover pixel 0 .. (n - 1) * spacing, one past the last pixel; the white noise
  // extends `radius` nodes beyond them on every side so the field has no border effect.
  const size_t nx = static_cast<size_t>((width - 1) / spacing + 2);
  const size_t ny = static_cast<size_t>((height - 1) / spacing + 2);
  const size_t ex = nx + 2 * static_cast<size_t>(radius);
  const size_t ey = ny + 2 * static_cast<size_t>(radius);
  const size_t taps = kernel.size();
  // Horizontal pass straight from the hashed white noise: rows of the extended grid.
  std::vector<float> horizontal(ey * nx);
  ParallelRows(pool, ey, [&](size_t gy) {
    thread_local std::vector<double> white;
    white.resize(ex);
    for (size_t gx = 0; gx < ex; ++gx) white[gx] = CellVariate(mixed, gy * ex + gx);
    for (size_t gx = 0; gx < nx; ++gx) {
      double acc = 0.0;
      for (size_t j = 0; j < taps; ++j) acc += kernel[j] * white[gx + j];
      horizontal[gy * nx + gx] = static_cast<float>(acc);
    }
  });
  std::vector<float> grid(ny * nx);
  ParallelRows(pool, ny, [&](size_t gy) {
    for (size_t gx = 0; gx < nx; ++gx) {
      double acc = 0.0;
      for (size_t j = 0; j < taps; ++j) acc += kernel[j] * horizontal[(gy + j) * nx + gx];
      grid[gy * nx + gx] = static_cast<float>(acc);
    }
  });
  if (spacing == 1) {
    ParallelRows(pool, h, [&](size_t v) {
      std::copy_n(grid.begin() + static_cast<std::ptrdiff_t>(v * nx), w,
                  out->begin() + static_cast<std::ptrdiff_t>(v * w));
    });
    return;
  }
  // The Gaussian correlation is separable, so the interpolation's variance factor is the
  // product of the two axes' factors.
  const AxisMap mu = MakeAxisMap(width, spacing, rho1);
  const AxisMap mv = MakeAxisMap(height, spacing, rho1);
  ParallelRows(pool, h, [&](size_t v) {
    const size_t gy = static_cast<size_t>(mv.node[v]);
    const float b = mv.frac[v];
    const float* row0 = grid.data() + gy * nx;
    const float* row1 = row0 + nx;
    for (size_t u = 0; u < w; ++u) {
      const size_t gx = static_cast<size_t>(mu.node[u]);
      const float a = mu.frac[u];
      const float top = row0[gx] + a * (row0[gx + 1] - row0[gx]);
      const float bottom = row1[gx] + a * (row1[gx + 1] - row1[gx]);
      (*out)[v * w + u] = (top + b * (bottom - top)) * mu.inv_sd[u] * mv.inv_sd[v];
    }
  });
}

}  // namespace clutterseg::synth::internal
