#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace clutterseg::optimize {

/// Minimum-cost assignment (the linear assignment problem) on a dense rectangular cost
/// matrix, by the O(n^2 m) shortest augmenting path form of the Hungarian method with dual
/// potentials (Kuhn-Munkres as refined by Jonker and Volgenant), n = min(rows, cols).
///
/// Every row is assigned a distinct column when rows <= cols; otherwise every column is
/// assigned a distinct row and rows - cols rows stay unassigned. Among the assignments of
/// that size the one of minimum total cost is returned. Ties are broken deterministically
/// (the same matrix always gives the same assignment). To get a maximum-weight matching in
/// which pairs may stay unmatched, pass cost = -weight with weight 0 for pairs that must not
/// match and drop the assigned pairs of weight 0 afterwards.
///
/// Thread-safety: none (one instance per thread). The work buffers are kept between calls,
/// so solving matrices no larger than before does not allocate.
class AssignmentSolver {
 public:
  AssignmentSolver() = default;

  /// Solves the assignment of `cost` (row-major, rows x cols, finite values; rows or cols may
  /// be 0). Fills `row_to_col` (resized to `rows`) with the column of each row, or -1 for an
  /// unassigned row, and returns the total cost of the assigned pairs.
  /// Complexity: O(min^2 * max) time for min = min(rows, cols), max = max(rows, cols).
  double Solve(std::span<const double> cost, int rows, int cols, std::vector<int32_t>* row_to_col);

 private:
  std::vector<double> u_, v_, min_slack_;
  std::vector<int32_t> match_, way_;
  std::vector<uint8_t> used_;
};

}  // namespace clutterseg::optimize
