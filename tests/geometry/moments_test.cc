#include "clutterseg/geometry/moments.h"

#include <array>
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

namespace clutterseg::geometry {
namespace {

// Reference: Eigen's iterative solver on the same matrix.
void CheckAgainstEigen(const double c[6], double eigenvalue_tol, double vector_tol) {
  Eigen::Matrix3d a;
  a << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> ref(a);
  double vec[3], l[3];
  SmallestEigenvector(c, vec, l);
  const Eigen::Vector3d rl = ref.eigenvalues().cwiseMax(0.0);
  EXPECT_NEAR(l[0], rl(2), eigenvalue_tol);
  EXPECT_NEAR(l[1], rl(1), eigenvalue_tol);
  EXPECT_NEAR(l[2], rl(0), eigenvalue_tol);
  const Eigen::Vector3d v(vec[0], vec[1], vec[2]);
  EXPECT_NEAR(v.norm(), 1.0, 1e-9);
  // The returned vector is an eigenvector of the smallest eigenvalue: A v = l3 v.
  const double residual = (a * v - ref.eigenvalues()(0) * v).norm();
  EXPECT_LT(residual, vector_tol) << "matrix " << a;
  if (ref.eigenvalues()(1) - ref.eigenvalues()(0) > 1e-3 * std::max(ref.eigenvalues()(2), 1e-30)) {
    EXPECT_GT(std::fabs(v.dot(ref.eigenvectors().col(0))), 1.0 - 1e-6);
  }
}

TEST(SmallestEigenvector, MatchesEigenOnRandomCovariances) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 2000; ++trial) {
    // Covariances of flat, elongated and round point clouds at the millimetre scale of voxels.
    Eigen::Matrix3d r = Eigen::Matrix3d::Zero();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r(i, j) = g(rng);
    const Eigen::Matrix3d q = Eigen::HouseholderQR<Eigen::Matrix3d>(r).householderQ();
    const double scale = 1e-5 * std::exp(g(rng));
    const Eigen::Vector3d d(scale, scale * std::pow(10.0, -3.0 * (trial % 4) / 3.0),
                            scale * std::pow(10.0, -(trial % 7)));
    const Eigen::Matrix3d a = q * d.asDiagonal() * q.transpose();
    const double c[6] = {a(0, 0), a(0, 1), a(0, 2), a(1, 1), a(1, 2), a(2, 2)};
    // Newton's method converges only linearly to a repeated smallest root: a few digits are
    // lost where eigenvalues coincide (harmless: the normal is then arbitrary anyway).
    CheckAgainstEigen(c, 1e-5 * scale, 1e-7 * scale);
  }
}

TEST(SmallestEigenvector, DegenerateMatrices) {
  const double zero[6] = {0, 0, 0, 0, 0, 0};
  const double iso[6] = {2e-6, 0, 0, 2e-6, 0, 2e-6};
  const double line[6] = {1e-4, 0, 0, 0, 0, 0};  // points along x: l2 = l3 = 0
  const double plane_xy[6] = {1e-4, 0, 0, 1e-4, 0, 0};
  for (const double* c : {zero, iso, line, plane_xy}) CheckAgainstEigen(c, 1e-12, 1e-12);
  double v[3], l[3];
  SmallestEigenvector(plane_xy, v, l);
  EXPECT_NEAR(std::fabs(v[2]), 1.0, 1e-12);
  SmallestEigenvector(line, v, l);
  EXPECT_NEAR(v[0], 0.0, 1e-12);
}

TEST(SmallestEigenvectors, BatchGivesExactlyTheSingleResults) {
  // Random covariances mixed with degenerate ones, in batches whose sizes are not multiples of
  // the group the solver iterates together: every result bit-identical to the single call.
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<std::array<double, 6>> c;
  for (int trial = 0; trial < 203; ++trial) {
    if (trial % 17 == 0) {
      c.push_back({0, 0, 0, 0, 0, 0});
    } else if (trial % 13 == 0) {
      c.push_back({1e-4, 0, 0, 1e-4, 0, 0});
    } else if (trial % 11 == 0) {
      c.push_back({2e-6, 0, 0, 2e-6, 0, 2e-6});
    } else {
      double r[9];
      for (double& x : r) x = 1e-3 * g(rng);
      c.push_back({r[0] * r[0] + r[1] * r[1] + r[2] * r[2], r[0] * r[3] + r[1] * r[4] + r[2] * r[5],
                   r[0] * r[6] + r[1] * r[7] + r[2] * r[8], r[3] * r[3] + r[4] * r[4] + r[5] * r[5],
                   r[3] * r[6] + r[4] * r[7] + r[5] * r[8],
                   r[6] * r[6] + r[7] * r[7] + r[8] * r[8]});
    }
  }
  for (size_t n : {size_t{0}, size_t{1}, size_t{3}, size_t{4}, size_t{5}, c.size()}) {
    std::vector<std::array<double, 3>> vec(n), l(n);
    SmallestEigenvectors(n, reinterpret_cast<const double(*)[6]>(c.data()),
                         reinterpret_cast<double(*)[3]>(vec.data()),
                         reinterpret_cast<double(*)[3]>(l.data()));
    for (size_t i = 0; i < n; ++i) {
      double v1[3], l1[3];
      SmallestEigenvector(c[i].data(), v1, l1);
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(vec[i][static_cast<size_t>(k)], v1[k]) << "matrix " << i << " of " << n;
        EXPECT_EQ(l[i][static_cast<size_t>(k)], l1[k]) << "matrix " << i << " of " << n;
      }
    }
  }
}

TEST(SummarizeMoments, PlaneFacingTheCamera) {
  // A 3 x 3 grid of points on the plane z = 1 - 0.5 x.
  double m[kNumMoments] = {};
  for (int i = -1; i <= 1; ++i) {
    for (int j = -1; j <= 1; ++j) {
      const double x = 0.01 * i, y = 0.01 * j, z = 1.0 - 0.5 * x;
      const double p[kNumMoments] = {1, x, y, z, x * x, x * y, x * z, y * y, y * z, z * z};
      for (int k = 0; k < kNumMoments; ++k) m[k] += p[k];
    }
  }
  ShapeSummary s;
  SummarizeMoments(m, &s);
  EXPECT_NEAR(s.centroid.z, 1.0, 1e-6);
  const double n = std::sqrt(1.25);
  EXPECT_NEAR(s.normal.x, -0.5 / n, 1e-5);
  EXPECT_NEAR(s.normal.z, -1.0 / n, 1e-5);  // towards the camera at the origin
  EXPECT_NEAR(s.curvature, 0.0, 1e-6);
  EXPECT_GT(s.eigenvalues.x, s.eigenvalues.y * 0.99);
}

}  // namespace
}  // namespace clutterseg::geometry
