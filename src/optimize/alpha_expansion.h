#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "clutterseg/optimize/max_flow.h"

namespace clutterseg::optimize {

/// A Potts energy over an undirected graph in CSR form:
///   E(l) = sum_i unary[i * num_labels + l_i] + sum_{i<j adjacent} w_ij [l_i != l_j].
/// The adjacency must be symmetric (j in N(i) iff i in N(j)), without self loops; each
/// undirected edge is counted once, with the weight stored in the slot of its smaller end.
struct PottsEnergy {
  int num_nodes{0};
  int num_labels{0};
  std::span<const float> unary;         ///< num_nodes x num_labels, row-major by node
  std::span<const uint32_t> offsets;    ///< num_nodes + 1 CSR offsets
  std::span<const uint32_t> neighbors;  ///< CSR neighbour lists
  std::span<const float> edge_weights;  ///< per CSR slot (>= 0), or empty for uniform_weight
  float uniform_weight{1.f};            ///< w_ij when edge_weights is empty, >= 0

  /// Energy of a labelling (`labels` has num_nodes entries in [0, num_labels)).
  double Evaluate(std::span<const int32_t> labels) const;

  /// Weight of CSR slot `s`.
  float weight(uint32_t s) const { return edge_weights.empty() ? uniform_weight : edge_weights[s]; }

  /// @throws std::invalid_argument when the array sizes disagree.
  void ValidateOrThrow() const;
};

/// Alpha-expansion (Boykov, Veksler, Zabih 2001) for PottsEnergy. Each expansion move is one
/// Boykov-Kolmogorov minimum cut on the Kolmogorov-Zabih construction; nodes already labelled
/// alpha are fixed and left out of the cut graph. For Potts the result is within a factor 2
/// of the global optimum. Moves are applied only when they lower the energy, so the energy
/// never increases.
///
/// Thread-safety: not reentrant (reuses the max-flow graph and buffers). Complexity: per
/// move, one max flow on at most num_nodes nodes and the graph's edges.
class AlphaExpansion {
 public:
  /// Minimizes `energy` starting from `*labels` (num_nodes entries in [0, num_labels)), or
  /// from the per-node minimum of the unary term when `*labels` is empty. Cycles over all
  /// labels until a full cycle makes no improvement or `max_cycles` cycles ran. Returns the
  /// final energy.
  /// @throws std::invalid_argument on inconsistent sizes or labels out of range.
  double Minimize(const PottsEnergy& energy, int max_cycles, std::vector<int32_t>* labels);

  /// Performs the optimal expansion move of label `alpha` from `*labels` and applies it when
  /// it lowers the energy. Returns the energy after the move.
  double Expand(const PottsEnergy& energy, int alpha, std::vector<int32_t>* labels);

  /// Cycles run by the last Minimize.
  int last_cycles() const { return last_cycles_; }
  /// Moves that lowered the energy in the last Minimize.
  int last_improving_moves() const { return last_moves_; }

 private:
  // Expand with the energy of `*labels` already known.
  double ExpandFrom(const PottsEnergy& energy, int alpha, double current,
                    std::vector<int32_t>* labels);

  void SumNodeWeights(const PottsEnergy& energy);  // fills node_weight_

  MaxFlow flow_;
  std::vector<double> node_weight_;  // per node: total weight of its edges
  std::vector<int32_t> var_of_node_;
  std::vector<double> cost_keep_;
  std::vector<double> cost_alpha_;
  std::vector<int32_t> proposal_;
  std::vector<int64_t> expanded_at_;  // per label: accepted moves before its last expansion
  int last_cycles_{0};
  int last_moves_{0};
};

}  // namespace clutterseg::optimize
