#include "clutterseg/geometry/neighbor_index.h"

#include <algorithm>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::geometry {
namespace {

// Squared distances from `q` to every point, with indices, nearest first (ties by index).
std::vector<std::pair<float, uint32_t>> BruteForce(const std::vector<float>& coords, int dim,
                                                   const float* q) {
  std::vector<std::pair<float, uint32_t>> d;
  const size_t n = coords.size() / static_cast<size_t>(dim);
  for (size_t i = 0; i < n; ++i) {
    float s = 0.f;
    for (int k = 0; k < dim; ++k) {
      const float e = coords[i * dim + k] - q[k];
      s += e * e;
    }
    d.emplace_back(s, static_cast<uint32_t>(i));
  }
  std::sort(d.begin(), d.end());
  return d;
}

// Points on a noisy surface (3-d) or a patch of view directions (2-d), with duplicates: the
// kind of data the segmenter indexes.
std::vector<float> RandomPoints(std::mt19937* rng, size_t n, int dim) {
  std::uniform_real_distribution<float> u(-0.2f, 0.2f);
  std::normal_distribution<float> noise(0.f, 0.003f);
  std::vector<float> coords;
  for (size_t i = 0; i < n; ++i) {
    const float x = u(*rng), y = u(*rng);
    coords.push_back(x);
    coords.push_back(y);
    if (dim == 3) coords.push_back(1.f + 0.3f * x + noise(*rng));
    if (i % 50 == 0) {  // an exact duplicate
      for (int k = 0; k < dim; ++k) coords.push_back(coords[coords.size() - dim]);
      ++i;
    }
  }
  coords.resize(n * static_cast<size_t>(dim));
  return coords;
}

TEST(NeighborIndex, NearestAndRadiusMatchBruteForceIn2dAnd3d) {
  std::mt19937 rng(5);
  NeighborIndex dut;
  for (int dim : {2, 3}) {
    for (size_t n : {1u, 7u, 300u, 5000u}) {
      const std::vector<float> coords = RandomPoints(&rng, n, dim);
      dut.Build(coords.data(), n, dim);
      ASSERT_EQ(dut.size(), n);
      ASSERT_EQ(dut.dim(), dim);
      for (int t = 0; t < 60; ++t) {
        // Queries at indexed points (the segmenter's use) and anywhere near them.
        float q[3];
        const size_t at = static_cast<size_t>(rng()) % n;
        for (int k = 0; k < dim; ++k) {
          q[k] =
              coords[at * dim + k] + (t % 2 == 0 ? 0.f : 0.01f * (static_cast<float>(t % 7) - 3));
        }
        const auto want = BruteForce(coords, dim, q);
        const size_t k = 1 + static_cast<size_t>(t) % 12;
        uint32_t index[NeighborIndex::kMaxNeighbors];
        float dist2[NeighborIndex::kMaxNeighbors];
        const size_t found = dut.Nearest(q, k, index, dist2);
        ASSERT_EQ(found, std::min(k, n));
        for (size_t j = 0; j < found; ++j) {
          // The same distances in order (ties may come in either order of index).
          EXPECT_FLOAT_EQ(dist2[j], want[j].first) << "dim " << dim << " n " << n << " j " << j;
          float s = 0.f;
          for (int c = 0; c < dim; ++c) {
            const float e = coords[index[j] * dim + c] - q[c];
            s += e * e;
          }
          EXPECT_FLOAT_EQ(s, dist2[j]);
        }
        const float radius = 0.004f + 0.01f * static_cast<float>(t % 3);
        std::vector<std::pair<uint32_t, float>> within;
        dut.WithinRadius(q, radius, &within);
        std::vector<uint32_t> got, expected;
        for (const auto& [i, d] : within) got.push_back(i);
        for (const auto& [d, i] : want) {
          if (d < radius * radius) expected.push_back(i);
        }
        std::sort(got.begin(), got.end());
        std::sort(expected.begin(), expected.end());
        EXPECT_EQ(got, expected) << "dim " << dim << " n " << n << " radius " << radius;
      }
    }
  }
}

TEST(NeighborIndex, RebuildsFromScratchAndHandlesEmptyInput) {
  NeighborIndex dut;
  dut.Build(nullptr, 0, 3);
  EXPECT_EQ(dut.size(), 0u);
  uint32_t index[4];
  float dist2[4];
  const float q[3] = {0.f, 0.f, 1.f};
  EXPECT_EQ(dut.Nearest(q, 4, index, dist2), 0u);
  std::vector<std::pair<uint32_t, float>> within{{7u, 1.f}};
  EXPECT_EQ(dut.WithinRadius(q, 1.f, &within), 0u);
  EXPECT_TRUE(within.empty());
  // A larger set, then a smaller one: nothing of the first remains.
  const std::vector<float> big = {0.f, 0.f, 1.f, 0.1f, 0.f, 1.f, 0.2f, 0.f, 1.f};
  dut.Build(big.data(), 3, 3);
  EXPECT_EQ(dut.Nearest(q, 4, index, dist2), 3u);
  const std::vector<float> one = {0.5f, 0.5f};
  dut.Build(one.data(), 1, 2);
  ASSERT_EQ(dut.Nearest(one.data(), 4, index, dist2), 1u);
  EXPECT_EQ(index[0], 0u);
  EXPECT_EQ(dist2[0], 0.f);
  EXPECT_THROW(dut.Build(one.data(), 1, 4), std::invalid_argument);
}

}  // namespace
}  // namespace clutterseg::geometry
