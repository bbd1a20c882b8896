#include "clutterseg/optimize/alpha_expansion.h"

#include <algorithm>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "tests/graph/synthetic_tiles.h"

namespace clutterseg::optimize {
namespace {

struct Problem {
  int n{0};
  int labels{0};
  std::vector<float> unary;
  std::vector<uint32_t> offsets, adjacency;
  std::vector<float> weights;  // per slot, symmetric

  PottsEnergy Energy() const {
    PottsEnergy e;
    e.num_nodes = n;
    e.num_labels = labels;
    e.unary = unary;
    e.offsets = offsets;
    e.neighbors = adjacency;
    e.edge_weights = weights;
    return e;
  }
};

Problem MakeProblem(std::mt19937* rng, int n, int labels, double density, float unary_scale = 3.f) {
  Problem p;
  p.n = n;
  p.labels = labels;
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int i = 0; i < n * labels; ++i) p.unary.push_back(unary_scale * u(*rng));
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  std::vector<float> w_of_edge;
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      if (u(*rng) < density) edges.emplace_back(i, j);
    }
  }
  graph::testing::BuildCsr(n, edges, &p.offsets, &p.adjacency);
  // Symmetric weights: a function of the unordered pair.
  std::vector<float> pair_w(static_cast<size_t>(n) * n);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      pair_w[static_cast<size_t>(i) * n + j] = pair_w[static_cast<size_t>(j) * n + i] =
          2.f * u(*rng);
    }
  }
  for (int i = 0; i < n; ++i) {
    for (uint32_t s = p.offsets[i]; s < p.offsets[i + 1]; ++s) {
      p.weights.push_back(pair_w[static_cast<size_t>(i) * n + p.adjacency[s]]);
    }
  }
  return p;
}

double BruteForceOptimum(const PottsEnergy& e) {
  std::vector<int32_t> lab(e.num_nodes, 0);
  double best = std::numeric_limits<double>::infinity();
  for (;;) {
    best = std::min(best, e.Evaluate(lab));
    int k = 0;
    while (k < e.num_nodes && ++lab[k] == e.num_labels) lab[k++] = 0;
    if (k == e.num_nodes) break;
  }
  return best;
}

// Best energy over all expansion moves of `alpha` from `labels`.
double BestExpansion(const PottsEnergy& e, const std::vector<int32_t>& labels, int alpha) {
  double best = std::numeric_limits<double>::infinity();
  std::vector<int32_t> lab(labels.size());
  for (uint32_t m = 0; m < (1u << e.num_nodes); ++m) {
    for (int i = 0; i < e.num_nodes; ++i) lab[i] = ((m >> i) & 1u) ? alpha : labels[i];
    best = std::min(best, e.Evaluate(lab));
  }
  return best;
}

// Runs every expansion move of `trials` random problems (`make(trial)`) from random
// labellings and checks each against brute force.
template <typename MakeProblemFn>
void ExpectEveryMoveOptimal(std::mt19937* rng, int trials, MakeProblemFn make) {
  AlphaExpansion dut;
  for (int trial = 0; trial < trials; ++trial) {
    const Problem p = make(trial);
    const PottsEnergy e = p.Energy();
    std::uniform_int_distribution<int> pick(0, p.labels - 1);
    std::vector<int32_t> lab(p.n);
    for (auto& l : lab) l = pick(*rng);
    for (int alpha = 0; alpha < p.labels; ++alpha) {
      const double expected = BestExpansion(e, lab, alpha);
      const double before = e.Evaluate(lab);
      const double after = dut.Expand(e, alpha, &lab);
      ASSERT_NEAR(after, expected, 1e-5) << "trial " << trial << " alpha " << alpha;
      ASSERT_NEAR(after, e.Evaluate(lab), 1e-9);
      ASSERT_LE(after, before + 1e-12);
    }
  }
}

TEST(AlphaExpansion, EachMoveIsTheOptimalExpansion) {
  std::mt19937 rng(42);
  ExpectEveryMoveOptimal(
      &rng, 300, [&](int trial) { return MakeProblem(&rng, 2 + trial % 9, 2 + trial % 3, 0.5); });
}

// Unary costs far above the edge weights: most nodes cannot profit from alpha and are left
// out of the move's graph. The move must still be the optimal expansion.
TEST(AlphaExpansion, MovesStayOptimalWhenMostNodesAreFixed) {
  std::mt19937 rng(7);
  ExpectEveryMoveOptimal(&rng, 300, [&](int trial) {
    return MakeProblem(&rng, 4 + trial % 8, 2 + trial % 4, 0.6, trial % 2 == 0 ? 4.f : 8.f);
  });
}

TEST(AlphaExpansion, WithinFactorTwoOfGlobalOptimum) {
  std::mt19937 rng(7);
  AlphaExpansion dut;
  int exact = 0;
  const int trials = 300;
  for (int trial = 0; trial < trials; ++trial) {
    const int n = 3 + trial % 6;       // up to 8 nodes
    const int labels = 3 + trial % 2;  // 3-4 labels
    const Problem p = MakeProblem(&rng, n, labels, 0.6);
    const PottsEnergy e = p.Energy();
    std::vector<int32_t> lab;
    const double found = dut.Minimize(e, 10, &lab);
    const double optimum = BruteForceOptimum(e);
    ASSERT_NEAR(found, e.Evaluate(lab), 1e-9);
    ASSERT_GE(found, optimum - 1e-9);
    ASSERT_LE(found, 2.0 * optimum + 1e-9) << "trial " << trial;
    if (found <= optimum + 1e-6) ++exact;
  }
  // Expansion is usually exact on such small problems.
  EXPECT_GT(exact, trials / 2);
}

TEST(AlphaExpansion, EnergyNeverIncreasesAcrossMoves) {
  std::mt19937 rng(11);
  AlphaExpansion dut;
  for (int trial = 0; trial < 20; ++trial) {
    const Problem p = MakeProblem(&rng, 60, 5, 0.08);
    const PottsEnergy e = p.Energy();
    std::vector<int32_t> lab(p.n, 0);
    double energy = e.Evaluate(lab);
    for (int cycle = 0; cycle < 3; ++cycle) {
      for (int alpha = 0; alpha < p.labels; ++alpha) {
        const double next = dut.Expand(e, alpha, &lab);
        ASSERT_LE(next, energy + 1e-12);
        energy = next;
      }
    }
    // Minimize from the same start reaches an energy no worse than the initial one, and a
    // local optimum: no single expansion improves it further.
    std::vector<int32_t> lab2(p.n, 0);
    const double start = e.Evaluate(lab2);
    const double final_energy = dut.Minimize(e, 50, &lab2);
    EXPECT_LE(final_energy, start);
    for (int alpha = 0; alpha < p.labels; ++alpha) {
      std::vector<int32_t> copy = lab2;
      EXPECT_NEAR(dut.Expand(e, alpha, &copy), final_energy, 1e-9);
    }
  }
}

TEST(AlphaExpansion, UniformWeightAndSmoothing) {
  // A chain of 10 nodes: unary prefers label 1 on node 4 only; strong smoothing wins.
  Problem p;
  p.n = 10;
  p.labels = 2;
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  for (int i = 0; i + 1 < p.n; ++i) edges.emplace_back(i, i + 1);
  graph::testing::BuildCsr(p.n, edges, &p.offsets, &p.adjacency);
  for (int i = 0; i < p.n; ++i) {
    p.unary.push_back(i == 4 ? 1.f : 0.f);
    p.unary.push_back(i == 4 ? 0.f : 1.f);
  }
  PottsEnergy e = p.Energy();
  e.edge_weights = {};
  e.uniform_weight = 0.1f;
  AlphaExpansion dut;
  std::vector<int32_t> lab;
  EXPECT_NEAR(dut.Minimize(e, 5, &lab), 0.2, 1e-6);
  EXPECT_EQ(lab[4], 1);
  e.uniform_weight = 1.f;
  lab.clear();
  EXPECT_NEAR(dut.Minimize(e, 5, &lab), 1.0, 1e-6);
  EXPECT_EQ(lab, std::vector<int32_t>(p.n, 0));
}

TEST(AlphaExpansion, RejectsBadInput) {
  std::mt19937 rng(1);
  const Problem p = MakeProblem(&rng, 4, 3, 0.5);
  PottsEnergy e = p.Energy();
  AlphaExpansion dut;
  std::vector<int32_t> lab = {0, 1, 5, 0};
  EXPECT_THROW(dut.Minimize(e, 3, &lab), std::invalid_argument);
  lab = {0, 1};
  EXPECT_THROW(dut.Minimize(e, 3, &lab), std::invalid_argument);
  e.num_labels = 4;  // unary size no longer matches
  lab.clear();
  EXPECT_THROW(dut.Minimize(e, 3, &lab), std::invalid_argument);
}

}  // namespace
}  // namespace clutterseg::optimize
