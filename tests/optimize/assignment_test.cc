#include "clutterseg/optimize/assignment.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::optimize {
namespace {

// The minimum total cost over every assignment of min(rows, cols) pairs, by enumeration.
double BruteForce(const std::vector<double>& cost, int rows, int cols) {
  const bool transposed = rows > cols;
  const int n = transposed ? cols : rows;
  const int m = transposed ? rows : cols;
  auto c = [&](int i, int j) {
    return transposed ? cost[static_cast<size_t>(j) * cols + i]
                      : cost[static_cast<size_t>(i) * cols + j];
  };
  // Every injective map of the n left nodes into the m right nodes: the first n entries of
  // every permutation of 0..m-1 (repeats are harmless for a minimum).
  std::vector<int> perm(static_cast<size_t>(m));
  std::iota(perm.begin(), perm.end(), 0);
  double best = std::numeric_limits<double>::infinity();
  do {
    double sum = 0.0;
    for (int i = 0; i < n; ++i) sum += c(i, perm[static_cast<size_t>(i)]);
    best = std::min(best, sum);
  } while (std::next_permutation(perm.begin(), perm.end()));
  return best;
}

// The assignment is a valid one of min(rows, cols) distinct pairs; returns its cost.
double CheckedCost(const std::vector<double>& cost, int rows, int cols,
                   const std::vector<int32_t>& row_to_col) {
  EXPECT_EQ(row_to_col.size(), static_cast<size_t>(rows));
  std::vector<int> used(static_cast<size_t>(cols), 0);
  int assigned = 0;
  double sum = 0.0;
  for (int r = 0; r < rows; ++r) {
    const int32_t c = row_to_col[static_cast<size_t>(r)];
    if (c < 0) continue;
    EXPECT_LT(c, cols);
    EXPECT_EQ(used[static_cast<size_t>(c)]++, 0) << "column " << c << " assigned twice";
    sum += cost[static_cast<size_t>(r) * cols + c];
    ++assigned;
  }
  EXPECT_EQ(assigned, std::min(rows, cols));
  return sum;
}

TEST(AssignmentSolver, MatchesBruteForceOnRandomMatrices) {
  std::mt19937 rng(7);
  AssignmentSolver dut;
  std::vector<int32_t> row_to_col;
  int checked = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int rows = std::uniform_int_distribution<int>(1, 7)(rng);
    const int cols = std::uniform_int_distribution<int>(1, 7)(rng);
    // Every third matrix has small integer costs, so ties are frequent.
    const bool ties = trial % 3 == 0;
    std::uniform_real_distribution<double> real(-5.0, 5.0);
    std::uniform_int_distribution<int> small(0, 3);
    std::vector<double> cost(static_cast<size_t>(rows) * cols);
    for (double& c : cost) c = ties ? small(rng) : real(rng);
    const double total = dut.Solve(cost, rows, cols, &row_to_col);
    const double expected = BruteForce(cost, rows, cols);
    EXPECT_NEAR(total, expected, 1e-9) << rows << "x" << cols << " trial " << trial;
    EXPECT_NEAR(CheckedCost(cost, rows, cols, row_to_col), total, 1e-9);
    ++checked;
  }
  EXPECT_EQ(checked, 3000);
}

TEST(AssignmentSolver, MaximumWeightMatchingLeavesZeroWeightPairsOut) {
  // Weights: row 0 matches column 1 only, row 1 nothing, row 2 prefers column 1 but yields it.
  const std::vector<double> weight = {0, 5, 0,  //
                                      0, 0, 0,  //
                                      0, 4, 3};
  std::vector<double> cost(weight.size());
  for (size_t k = 0; k < weight.size(); ++k) cost[k] = -weight[k];
  AssignmentSolver dut;
  std::vector<int32_t> row_to_col;
  EXPECT_DOUBLE_EQ(dut.Solve(cost, 3, 3, &row_to_col), -8.0);
  EXPECT_EQ(row_to_col[0], 1);
  EXPECT_EQ(row_to_col[2], 2);
  EXPECT_EQ(weight[static_cast<size_t>(3 + row_to_col[1])], 0.0);  // dropped by the caller
}

TEST(AssignmentSolver, EmptyAndDeterministic) {
  AssignmentSolver dut;
  std::vector<int32_t> row_to_col{5, 6};
  EXPECT_EQ(dut.Solve({}, 0, 4, &row_to_col), 0.0);
  EXPECT_TRUE(row_to_col.empty());
  EXPECT_EQ(dut.Solve({}, 3, 0, &row_to_col), 0.0);
  EXPECT_EQ(row_to_col, (std::vector<int32_t>{-1, -1, -1}));
  // All-equal costs: any assignment is optimal; the same one comes back every time.
  const std::vector<double> flat(20, 1.0);
  std::vector<int32_t> first, again;
  dut.Solve(flat, 4, 5, &first);
  AssignmentSolver other;
  other.Solve(flat, 4, 5, &again);
  EXPECT_EQ(first, again);
  dut.Solve(flat, 5, 4, &again);
  EXPECT_EQ(std::count(again.begin(), again.end(), -1), 1);
}

}  // namespace
}  // namespace clutterseg::optimize
