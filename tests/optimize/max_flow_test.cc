#include "clutterseg/optimize/max_flow.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::optimize {
namespace {

struct RandomGraph {
  int n{0};
  std::vector<double> cs, ct;  // terminal capacities
  struct Edge {
    int i, j;
    double cij, cji;
  };
  std::vector<Edge> edges;
};

RandomGraph MakeRandomGraph(std::mt19937* rng, int n, double edge_probability, bool integer) {
  RandomGraph g;
  g.n = n;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto cap = [&](double scale) {
    const double v = u(*rng) * scale;
    return integer ? std::floor(v) : v;
  };
  for (int i = 0; i < n; ++i) {
    // Some nodes have no terminal link, some only one.
    const double r = u(*rng);
    g.cs.push_back(r < 0.25 ? 0.0 : cap(10.0));
    g.ct.push_back(r > 0.75 ? 0.0 : cap(10.0));
  }
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      if (u(*rng) < edge_probability) {
        g.edges.push_back({i, j, cap(8.0), u(*rng) < 0.3 ? 0.0 : cap(8.0)});
      }
    }
  }
  return g;
}

void Load(const RandomGraph& g, MaxFlow* dut) {
  dut->Reset(g.n, static_cast<int>(g.edges.size()));
  for (int i = 0; i < g.n; ++i) dut->AddTerminal(i, g.cs[i], g.ct[i]);
  for (const auto& e : g.edges) dut->AddEdge(e.i, e.j, e.cij, e.cji);
}

// Value of the cut where bit i of `source_set` puts node i on the source side.
double CutValue(const RandomGraph& g, uint32_t source_set) {
  auto in_s = [&](int i) { return ((source_set >> i) & 1u) != 0; };
  double c = 0.0;
  for (int i = 0; i < g.n; ++i) c += in_s(i) ? g.ct[i] : g.cs[i];
  for (const auto& e : g.edges) {
    if (in_s(e.i) && !in_s(e.j)) c += e.cij;
    if (in_s(e.j) && !in_s(e.i)) c += e.cji;
  }
  return c;
}

double BruteForceMinCut(const RandomGraph& g) {
  double best = std::numeric_limits<double>::infinity();
  for (uint32_t s = 0; s < (1u << g.n); ++s) best = std::min(best, CutValue(g, s));
  return best;
}

// Edmonds-Karp on a dense residual matrix with the source n and the sink n + 1.
double EdmondsKarp(const RandomGraph& g) {
  const int n = g.n + 2, s = g.n, t = g.n + 1;
  std::vector<double> r(static_cast<size_t>(n) * n, 0.0);
  auto at = [&](int a, int b) -> double& { return r[static_cast<size_t>(a) * n + b]; };
  for (int i = 0; i < g.n; ++i) {
    at(s, i) += g.cs[i];
    at(i, t) += g.ct[i];
  }
  for (const auto& e : g.edges) {
    at(e.i, e.j) += e.cij;
    at(e.j, e.i) += e.cji;
  }
  double flow = 0.0;
  std::vector<int> prev(n);
  for (;;) {
    std::fill(prev.begin(), prev.end(), -1);
    prev[s] = s;
    std::queue<int> q;
    q.push(s);
    while (!q.empty() && prev[t] < 0) {
      const int a = q.front();
      q.pop();
      for (int b = 0; b < n; ++b) {
        if (prev[b] < 0 && at(a, b) > 1e-12) {
          prev[b] = a;
          q.push(b);
        }
      }
    }
    if (prev[t] < 0) break;
    double b = std::numeric_limits<double>::infinity();
    for (int v = t; v != s; v = prev[v]) b = std::min(b, at(prev[v], v));
    for (int v = t; v != s; v = prev[v]) {
      at(prev[v], v) -= b;
      at(v, prev[v]) += b;
    }
    flow += b;
  }
  return flow;
}

TEST(MaxFlow, MatchesBruteForceOnSmallRandomGraphs) {
  std::mt19937 rng(1234);
  MaxFlow dut;
  int checked = 0;
  for (int trial = 0; trial < 600; ++trial) {
    const int n = 1 + trial % 12;
    const double density = 0.15 + 0.7 * ((trial / 12) % 5) / 4.0;
    const RandomGraph g = MakeRandomGraph(&rng, n, density, trial % 2 == 0);
    Load(g, &dut);
    const double flow = dut.Solve();
    const double best = BruteForceMinCut(g);
    ASSERT_NEAR(flow, best, 1e-9 * (1.0 + best)) << "trial " << trial << " n " << n;
    // The reported partition is a minimum cut.
    uint32_t set = 0;
    for (int i = 0; i < n; ++i) set |= dut.InSourceSet(i) ? (1u << i) : 0u;
    ASSERT_NEAR(CutValue(g, set), best, 1e-9 * (1.0 + best)) << "trial " << trial;
    ++checked;
  }
  EXPECT_EQ(checked, 600);
}

TEST(MaxFlow, MatchesEdmondsKarpOnLargerRandomGraphs) {
  std::mt19937 rng(99);
  MaxFlow dut;
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 200;
    RandomGraph g = MakeRandomGraph(&rng, 0, 0.0, false);
    g.n = n;
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < n; ++i) {
      g.cs.push_back(u(rng) < 0.1 ? 5.0 * u(rng) : 0.0);
      g.ct.push_back(u(rng) < 0.1 ? 5.0 * u(rng) : 0.0);
    }
    // A sparse graph: a ring plus random chords (like a supervoxel adjacency).
    for (int i = 0; i < n; ++i) g.edges.push_back({i, (i + 1) % n, 3.0 * u(rng), 3.0 * u(rng)});
    std::uniform_int_distribution<int> pick(0, n - 1);
    for (int k = 0; k < 3 * n; ++k) {
      const int a = pick(rng), b = pick(rng);
      if (a != b) g.edges.push_back({a, b, 2.0 * u(rng), 2.0 * u(rng)});
    }
    Load(g, &dut);
    const double flow = dut.Solve();
    const double reference = EdmondsKarp(g);
    ASSERT_NEAR(flow, reference, 1e-8 * (1.0 + reference)) << "trial " << trial;
    // Cut value of the reported partition equals the flow.
    double cut = 0.0;
    for (int i = 0; i < n; ++i) cut += dut.InSourceSet(i) ? g.ct[i] : g.cs[i];
    for (const auto& e : g.edges) {
      if (dut.InSourceSet(e.i) && !dut.InSourceSet(e.j)) cut += e.cij;
      if (dut.InSourceSet(e.j) && !dut.InSourceSet(e.i)) cut += e.cji;
    }
    EXPECT_NEAR(cut, flow, 1e-8 * (1.0 + flow));
  }
}

TEST(MaxFlow, NegativeTerminalCapacitiesShiftTheCut) {
  // Costs: node 0 on the sink side costs -2 (a reward), on the source side 1.
  MaxFlow dut;
  dut.Reset(2);
  dut.AddTerminal(0, -2.0, 1.0);
  dut.AddTerminal(1, 4.0, 0.5);
  dut.AddEdge(0, 1, 1.0, 3.0);
  // Cuts: {0,1} in S: 1 + 0.5 = 1.5; {0} in S: 1 + 4 + 1 = 6; {1} in S: -2 + 0.5 + 3 = 1.5;
  // none in S: -2 + 4 = 2.
  EXPECT_NEAR(dut.Solve(), 1.5, 1e-12);
}

TEST(MaxFlow, SimpleChain) {
  MaxFlow dut;
  dut.Reset(3);
  dut.AddTerminal(0, 5.0, 0.0);
  dut.AddTerminal(2, 0.0, 4.0);
  dut.AddEdge(0, 1, 3.0, 0.0);
  dut.AddEdge(1, 2, 2.5, 0.0);
  EXPECT_DOUBLE_EQ(dut.Solve(), 2.5);
  EXPECT_TRUE(dut.InSourceSet(0));
  EXPECT_TRUE(dut.InSourceSet(1));
  EXPECT_FALSE(dut.InSourceSet(2));
  // Reset reuses the instance.
  dut.Reset(1);
  dut.AddTerminal(0, 1.0, 2.0);
  EXPECT_DOUBLE_EQ(dut.Solve(), 1.0);
  EXPECT_FALSE(dut.InSourceSet(0));
}

}  // namespace
}  // namespace clutterseg::optimize
