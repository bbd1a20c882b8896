#include "clutterseg/optimize/alpha_expansion.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "clutterseg/core/assert.h"

namespace clutterseg::optimize {
namespace {

// Relative improvement below which a move is treated as no change (guards rounding loops).
constexpr double kRelativeTolerance = 1e-12;
// var_of_node_ of nodes outside the graph of a move.
constexpr int32_t kFixedAlpha = -1;  // labelled alpha already
constexpr int32_t kFixedKeep = -2;   // keeps its label in every minimum

}  // namespace

void PottsEnergy::ValidateOrThrow() const {
  const auto n = static_cast<size_t>(num_nodes);
  if (num_nodes < 0 || num_labels < 1) {
    throw std::invalid_argument("PottsEnergy: num_nodes = " + std::to_string(num_nodes) +
                                ", num_labels = " + std::to_string(num_labels));
  }
  if (unary.size() != n * static_cast<size_t>(num_labels)) {
    throw std::invalid_argument("PottsEnergy: unary has " + std::to_string(unary.size()) +
                                " entries, expected num_nodes x num_labels");
  }
  if (offsets.size() != n + 1 || offsets.back() != neighbors.size()) {
    throw std::invalid_argument("PottsEnergy: offsets has " + std::to_string(offsets.size()) +
                                " entries for " + std::to_string(n) + " nodes and " +
                                std::to_string(neighbors.size()) + " neighbour slots");
  }
  if (!edge_weights.empty() && edge_weights.size() != neighbors.size()) {
    throw std::invalid_argument("PottsEnergy: edge_weights has " +
                                std::to_string(edge_weights.size()) + " entries, expected " +
                                std::to_string(neighbors.size()));
  }
  if (!(uniform_weight >= 0.f)) {
    throw std::invalid_argument("PottsEnergy: uniform_weight = " + std::to_string(uniform_weight) +
                                " must be >= 0");
  }
}

double PottsEnergy::Evaluate(std::span<const int32_t> labels) const {
  CLUTTERSEG_DEMAND(labels.size() == static_cast<size_t>(num_nodes));
  double e = 0.0;
  const auto L = static_cast<size_t>(num_labels);
  for (int i = 0; i < num_nodes; ++i) {
    e += unary[static_cast<size_t>(i) * L + static_cast<size_t>(labels[i])];
    for (uint32_t s = offsets[i]; s < offsets[i + 1]; ++s) {
      const uint32_t j = neighbors[s];
      if (j > static_cast<uint32_t>(i) && labels[i] != labels[j]) e += weight(s);
    }
  }
  return e;
}

double AlphaExpansion::Expand(const PottsEnergy& en, int alpha, std::vector<int32_t>* labels) {
  CLUTTERSEG_DEMAND(labels->size() == static_cast<size_t>(en.num_nodes));
  SumNodeWeights(en);
  return ExpandFrom(en, alpha, en.Evaluate(*labels), labels);
}

void AlphaExpansion::SumNodeWeights(const PottsEnergy& en) {
  const auto n = static_cast<size_t>(en.num_nodes);
  node_weight_.assign(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    double sum = 0.0;
    for (uint32_t s = en.offsets[i]; s < en.offsets[i + 1]; ++s) sum += en.weight(s);
    node_weight_[i] = sum;
  }
}

double AlphaExpansion::ExpandFrom(const PottsEnergy& en, int alpha, double before,
                                  std::vector<int32_t>* labels) {
  CLUTTERSEG_DEMAND(alpha >= 0 && alpha < en.num_labels);
  CLUTTERSEG_DEMAND(labels->size() == static_cast<size_t>(en.num_nodes));
  const int n = en.num_nodes;
  const auto L = static_cast<size_t>(en.num_labels);
  const std::vector<int32_t>& lab = *labels;

  // Variables: nodes not yet labelled alpha. x = 0 keeps the label (source side),
  // x = 1 takes alpha (sink side). A node whose unary cost rises by more than the total
  // weight of its edges when it takes alpha keeps its label in every minimum (its edges can
  // lower the energy by at most that total), so it is fixed instead: most patches are far
  // from most planes, and the graph shrinks to the nodes alpha can win.
  var_of_node_.resize(n);
  int num_vars = 0;
  for (int i = 0; i < n; ++i) {
    const size_t row = static_cast<size_t>(i) * L;
    if (lab[i] == alpha) {
      var_of_node_[i] = kFixedAlpha;
    } else if (double{en.unary[row + static_cast<size_t>(alpha)]} -
                   double{en.unary[row + static_cast<size_t>(lab[i])]} >
               node_weight_[static_cast<size_t>(i)]) {
      var_of_node_[i] = kFixedKeep;
    } else {
      var_of_node_[i] = num_vars++;
    }
  }
  if (num_vars == 0) return before;
  cost_keep_.assign(num_vars, 0.0);
  cost_alpha_.assign(num_vars, 0.0);
  for (int i = 0; i < n; ++i) {
    const int v = var_of_node_[i];
    if (v < 0) continue;
    cost_keep_[v] = en.unary[static_cast<size_t>(i) * L + static_cast<size_t>(lab[i])];
    cost_alpha_[v] = en.unary[static_cast<size_t>(i) * L + static_cast<size_t>(alpha)];
  }
  flow_.Reset(num_vars, static_cast<int>(en.neighbors.size() / 2));
  // An edge to a fixed node is a unary term of the variable: next to an alpha node, keeping
  // costs w; next to a node keeping label l, keeping costs w [l != l_j] and alpha costs w.
  auto fixed_neighbour = [&](int fixed_node, int var_node, int var, double w) {
    if (var_of_node_[fixed_node] == kFixedAlpha) {
      cost_keep_[var] += w;
    } else {
      if (lab[fixed_node] != lab[var_node]) cost_keep_[var] += w;
      cost_alpha_[var] += w;
    }
  };
  // Edges are visited from their variables only (fixed nodes are most of the graph): an edge
  // to a fixed node once, from its variable; an edge between variables once, from the lower.
  for (int i = 0; i < n; ++i) {
    const int vi = var_of_node_[i];
    if (vi < 0) continue;
    for (uint32_t s = en.offsets[i]; s < en.offsets[i + 1]; ++s) {
      const auto j = static_cast<int>(en.neighbors[s]);
      const int vj = var_of_node_[j];
      if (vj >= 0 && j <= i) continue;
      const double w = en.weight(s);
      if (w == 0.0) continue;
      if (vj < 0) {
        fixed_neighbour(j, i, vi, w);
        continue;
      }
      // E00 = w[l_i != l_j], E01 = E10 = w, E11 = 0 (Kolmogorov-Zabih decomposition):
      // E = E00 + (w - E00) x_i - w x_j + (2w - E00) (1 - x_i) x_j, and symmetrically.
      const double e00 = lab[i] != lab[j] ? w : 0.0;
      cost_alpha_[vi] += w - e00;
      cost_keep_[vj] += w;  // -w x_j = -w + w (1 - x_j); the constant is dropped
      flow_.AddEdge(vi, vj, 2.0 * w - e00, 0.0);
    }
  }
  for (int v = 0; v < num_vars; ++v) flow_.AddTerminal(v, cost_alpha_[v], cost_keep_[v]);
  flow_.Solve();

  proposal_.assign(lab.begin(), lab.end());
  bool changed = false;
  for (int i = 0; i < n; ++i) {
    const int v = var_of_node_[i];
    if (v >= 0 && !flow_.InSourceSet(v)) {
      proposal_[i] = alpha;
      changed = true;
    }
  }
  if (!changed) return before;
  const double after = en.Evaluate(proposal_);
  if (after < before - kRelativeTolerance * (1.0 + std::abs(before))) {
    labels->swap(proposal_);
    return after;
  }
  return before;
}

double AlphaExpansion::Minimize(const PottsEnergy& en, int max_cycles,
                                std::vector<int32_t>* labels) {
  en.ValidateOrThrow();
  const int n = en.num_nodes;
  const auto L = static_cast<size_t>(en.num_labels);
  last_cycles_ = 0;
  last_moves_ = 0;
  if (labels->empty()) {
    labels->resize(n);
    for (int i = 0; i < n; ++i) {
      const float* u = en.unary.data() + static_cast<size_t>(i) * L;
      int32_t best = 0;
      for (size_t l = 1; l < L; ++l) {
        if (u[l] < u[best]) best = static_cast<int32_t>(l);
      }
      (*labels)[i] = best;
    }
  } else if (labels->size() != static_cast<size_t>(n)) {
    throw std::invalid_argument("AlphaExpansion: " + std::to_string(labels->size()) +
                                " initial labels for " + std::to_string(n) + " nodes");
  }
  for (int32_t l : *labels) {
    if (l < 0 || static_cast<size_t>(l) >= L) {
      throw std::invalid_argument("AlphaExpansion: initial label " + std::to_string(l) +
                                  " out of range [0, " + std::to_string(L) + ")");
    }
  }
  double energy = en.Evaluate(*labels);
  if (en.num_labels == 1 || n == 0) return energy;
  SumNodeWeights(en);
  // An expansion move is optimal for its alpha: expanding alpha again before any other move
  // changed the labels cannot lower the energy, so it is skipped (the result is the same; the
  // last, confirming cycle mostly disappears).
  expanded_at_.assign(L, -1);
  int64_t version = 0;  // number of accepted moves so far
  for (int cycle = 0; cycle < max_cycles; ++cycle) {
    ++last_cycles_;
    bool improved = false;
    for (int alpha = 0; alpha < en.num_labels; ++alpha) {
      if (expanded_at_[static_cast<size_t>(alpha)] == version) continue;
      const double e = ExpandFrom(en, alpha, energy, labels);
      if (e < energy) {
        energy = e;
        improved = true;
        ++last_moves_;
        ++version;
      }
      expanded_at_[static_cast<size_t>(alpha)] = version;
    }
    if (!improved) break;
  }
  return energy;
}

}  // namespace clutterseg::optimize
