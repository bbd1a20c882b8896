#pragma once

#include <array>
#include <cstddef>

#include "clutterseg/core/types.h"

namespace clutterseg::geometry {

/// Raw moments of a point set, in this order: count, sums of x, y, z, and sums of the
/// products xx, xy, xz, yy, yz, zz (metres, square metres). Moments of a union of disjoint
/// sets are the sums of their moments.
inline constexpr int kNumMoments = 10;

/// Adds the point `p` (metres) to the nine sums x, y, z, xx, xy, xz, yy, yz, zz at `s` (the
/// moments after the count, for sums that keep their count apart).
inline void AddToSums(const core::Vec3f& p, double* s) {
  const double x = p.x, y = p.y, z = p.z;
  s[0] += x;
  s[1] += y;
  s[2] += z;
  s[3] += x * x;
  s[4] += x * y;
  s[5] += x * z;
  s[6] += y * y;
  s[7] += y * z;
  s[8] += z * z;
}

/// Adds the point `p` (metres) to the moments `m` (kNumMoments values, in the order above).
inline void AddToMoments(const core::Vec3f& p, double* m) {
  m[0] += 1.0;
  AddToSums(p, m + 1);
}

/// Second-order shape of a point set.
struct ShapeSummary {
  core::Vec3f centroid;               ///< mean, metres
  std::array<float, 6> covariance{};  ///< xx, xy, xz, yy, yz, zz (population), m^2
  core::Vec3f eigenvalues;            ///< of the covariance, l1 >= l2 >= l3 >= 0, m^2
  /// Unit eigenvector of l3 oriented towards the camera at the origin (normal . centroid <= 0);
  /// the direction to the camera when the eigenvector is degenerate.
  core::Vec3f normal;
  float curvature{0.f};  ///< surface variation l3 / (l1 + l2 + l3); 0 when all are 0
};

/// Smallest eigenpair of the symmetric positive semi-definite 3x3 matrix with entries `c` =
/// (xx, xy, xz, yy, yz, zz): fills the unit eigenvector of the smallest eigenvalue (sign
/// arbitrary; some unit vector orthogonal to the dominant direction when that eigenvalue is
/// repeated) and the eigenvalues l1 >= l2 >= l3 >= 0. The smallest eigenvalue comes from
/// Newton's method on the characteristic polynomial (no trigonometry), the eigenvector from
/// cross products: much cheaper than a full eigen-decomposition. Relative accuracy 1e-9 for
/// separated eigenvalues, about 1e-5 where the smallest is repeated. Pure; thread-safe.
void SmallestEigenvector(const double c[6], double vec[3], double eigenvalues[3]);

/// SmallestEigenvector of each of `n` matrices, with the same results; faster for many
/// matrices (their iterations overlap). Pure; thread-safe.
void SmallestEigenvectors(size_t n, const double (*c)[6], double (*vec)[3],
                          double (*eigenvalues)[3]);

/// Mean (metres) and population covariance (xx, xy, xz, yy, yz, zz; square metres) of the
/// points whose moments are `m` (kNumMoments values, count > 0). Pure; thread-safe.
void MomentsCovariance(const double* m, double mean[3], double cov[6]);

/// Covariance analysis of the points whose moments are `m` (kNumMoments values, count > 0).
/// Pure function; thread-safe.
void SummarizeMoments(const double* m, ShapeSummary* out);

}  // namespace clutterseg::geometry
