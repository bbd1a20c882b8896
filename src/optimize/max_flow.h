#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace clutterseg::optimize {

/// Maximum flow / minimum s-t cut with the Boykov-Kolmogorov algorithm (two search trees
/// grown from the source and the sink, augmentation along the found path, adoption of
/// orphans), on a flat graph of nodes and paired arcs. Capacities are doubles.
///
/// Usage: Reset, then AddTerminal / AddEdge, then Solve once, then InSourceSet. Terminal
/// capacities may be negative: AddTerminal(i, cs, ct) adds cs to the cost of putting i on
/// the sink side and ct to the cost of putting it on the source side, so Solve returns the
/// minimum of sum over cut edges of their capacity plus those terminal costs (which can be
/// negative then). Edge capacities must be >= 0.
///
/// Thread-safety: none (one instance per thread). Buffers are reused across Reset calls.
class MaxFlow {
 public:
  MaxFlow() = default;

  /// Clears the graph and creates `num_nodes` nodes with no edges; `expected_edges` reserves
  /// room for that many AddEdge calls.
  void Reset(int num_nodes, int expected_edges = 0);

  /// Adds capacities from the source to `node` (`cap_source`) and from `node` to the sink
  /// (`cap_sink`). Repeated calls accumulate.
  void AddTerminal(int node, double cap_source, double cap_sink);

  /// Adds the arc pair i -> j (capacity `cap_ij`) and j -> i (`cap_ji`); both >= 0, i != j.
  void AddEdge(int i, int j, double cap_ij, double cap_ji);

  /// Computes the maximum flow (= the minimum cut value, see above) and returns it.
  double Solve();

  /// After Solve: true when `node` is on the source side of the minimum cut (reachable from
  /// the source in the residual graph). Other nodes are on the sink side.
  bool InSourceSet(int node) const;

  int num_nodes() const { return static_cast<int>(nodes_.size()); }
  int num_edges() const { return static_cast<int>(arcs_.size() / 2); }

 private:
  static constexpr int32_t kNone = -1;      // free node
  static constexpr int32_t kTerminal = -2;  // parent is the source or sink
  static constexpr int32_t kOrphan = -3;

  struct Node {
    int32_t first_arc{-1};
    int32_t parent{kNone};  // arc from this node towards its parent, or kNone/kTerminal/kOrphan
    int32_t ts{0};          // time stamp of `dist`
    int32_t dist{0};        // distance to the terminal along the tree
    uint8_t is_sink{0};
    uint8_t in_queue{0};
    double tr_cap{0.0};  // > 0: residual from the source; < 0: residual to the sink
  };
  struct Arc {
    int32_t head{0};
    int32_t next{-1};  // next arc leaving the same node
    double r_cap{0.0};
  };

  void Activate(int32_t i);
  int32_t NextActive();
  void SetOrphan(int32_t i);
  void Augment(int32_t middle_arc);
  void ProcessSourceOrphan(int32_t i);
  void ProcessSinkOrphan(int32_t i);

  std::vector<Node> nodes_;
  std::vector<Arc> arcs_;       // arc a and a ^ 1 are reverses of each other
  std::vector<int32_t> queue_;  // ring buffer of active nodes (each at most once)
  size_t queue_head_{0};
  size_t queue_size_{0};
  std::vector<int32_t> orphans_;
  size_t orphan_head_{0};
  double flow_{0.0};
  int32_t time_{0};
  bool solved_{false};
};

}  // namespace clutterseg::optimize
