#include "clutterseg/optimize/assignment.h"

#include <algorithm>
#include <limits>

#include "clutterseg/core/assert.h"

namespace clutterseg::optimize {

double AssignmentSolver::Solve(std::span<const double> cost, int rows, int cols,
                               std::vector<int32_t>* row_to_col) {
  CLUTTERSEG_DEMAND(rows >= 0 && cols >= 0);
  CLUTTERSEG_DEMAND(cost.size() == static_cast<size_t>(rows) * static_cast<size_t>(cols));
  row_to_col->assign(static_cast<size_t>(rows), -1);
  if (rows == 0 || cols == 0) return 0.0;
  // The method assigns every one of n "left" nodes to one of m >= n "right" nodes; with more
  // rows than columns the columns are the left side.
  const bool transposed = rows > cols;
  const int n = transposed ? cols : rows;
  const int m = transposed ? rows : cols;
  auto c = [&](int i, int j) {  // 1-based left node i, right node j
    return transposed ? cost[static_cast<size_t>(j - 1) * cols + (i - 1)]
                      : cost[static_cast<size_t>(i - 1) * cols + (j - 1)];
  };
  constexpr double kInf = std::numeric_limits<double>::infinity();
  u_.assign(static_cast<size_t>(n) + 1, 0.0);
  v_.assign(static_cast<size_t>(m) + 1, 0.0);
  match_.assign(static_cast<size_t>(m) + 1, 0);  // right node j -> left node, 0 = free
  way_.assign(static_cast<size_t>(m) + 1, 0);
  min_slack_.resize(static_cast<size_t>(m) + 1);
  used_.resize(static_cast<size_t>(m) + 1);
  for (int i = 1; i <= n; ++i) {
    // Grow a tree of tight edges from left node i (attached to the virtual right node 0)
    // until it reaches a free right node, adjusting the potentials by the smallest slack.
    match_[0] = i;
    int j0 = 0;
    std::fill(min_slack_.begin(), min_slack_.end(), kInf);
    std::fill(used_.begin(), used_.end(), uint8_t{0});
    do {
      used_[j0] = 1;
      const int i0 = match_[j0];
      double delta = kInf;
      int j1 = 0;
      for (int j = 1; j <= m; ++j) {
        if (used_[j]) continue;
        const double slack = c(i0, j) - u_[i0] - v_[j];
        if (slack < min_slack_[j]) {
          min_slack_[j] = slack;
          way_[j] = j0;
        }
        if (min_slack_[j] < delta) {
          delta = min_slack_[j];
          j1 = j;
        }
      }
      CLUTTERSEG_DEMAND(j1 != 0);  // finite costs always leave a reachable column
      for (int j = 0; j <= m; ++j) {
        if (used_[j]) {
          u_[match_[j]] += delta;
          v_[j] -= delta;
        } else {
          min_slack_[j] -= delta;
        }
      }
      j0 = j1;
    } while (match_[j0] != 0);
    // Flip the augmenting path back to the root.
    do {
      const int j1 = way_[j0];
      match_[j0] = match_[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  double total = 0.0;
  for (int j = 1; j <= m; ++j) {
    const int i = match_[j];
    if (i == 0) continue;
    total += c(i, j);
    if (transposed) {
      (*row_to_col)[static_cast<size_t>(j - 1)] = i - 1;
    } else {
      (*row_to_col)[static_cast<size_t>(i - 1)] = j - 1;
    }
  }
  return total;
}

}  // namespace clutterseg::optimize
