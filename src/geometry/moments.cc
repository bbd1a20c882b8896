#include "clutterseg/geometry/moments.h"

#include <algorithm>
#include <cmath>

namespace clutterseg::geometry {

namespace {

// Smallest root of the characteristic polynomial f(l) = det(A - l I) by Newton's method from
// l = 0: A is positive semi-definite, so 0 <= l3 and f is decreasing and convex left of l3;
// the iterates rise monotonically to it. Nearly flat patches (l3 << l2) converge in two or
// three steps. Work on B = A / trace, whose eigenvalues lie in [0, 1]: f(l) = -l^3 + l^2 -
// m2 l + m3. Convergence is quadratic, so after a step below 1e-6 l the error is near
// 1e-12 l: stopping there instead of waiting for a step at rounding level saves one
// iteration of about five (segmentations of the mOSD and synthetic test frames unchanged).
// At a repeated root, where convergence is linear, either eigenvector of the pair is valid.
struct CharPoly {
  double trace{0.0};
  double m2{0.0};  // second and third invariants of B
  double m3{0.0};
};

CharPoly CharacteristicPolynomial(const double c[6]) {
  const double a00 = c[0], a01 = c[1], a02 = c[2], a11 = c[3], a12 = c[4], a22 = c[5];
  CharPoly p;
  p.trace = a00 + a11 + a22;
  if (!(p.trace > 0.0)) return p;
  const double s = 1.0 / p.trace;
  const double b00 = a00 * s, b01 = a01 * s, b02 = a02 * s, b11 = a11 * s, b12 = a12 * s,
               b22 = a22 * s;
  p.m2 = b00 * b11 - b01 * b01 + b00 * b22 - b02 * b02 + b11 * b22 - b12 * b12;
  p.m3 =
      b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02);
  return p;
}

// One Newton step on root estimate *l; returns whether another step is needed.
inline bool NewtonStep(const CharPoly& p, double* l) {
  const double f = ((-*l + 1.0) * *l - p.m2) * *l + p.m3;
  const double df = (-3.0 * *l + 2.0) * *l - p.m2;
  if (!(df < 0.0)) return false;  // at a repeated root (or rounding past it)
  const double step = f / df;
  *l -= step;
  return std::fabs(step) > 1e-6 * (*l + 1e-12);
}

constexpr int kMaxNewtonSteps = 60;

// Eigenvalues from the smallest root `l` of B's polynomial, and the eigenvector.
void FinishEigen(const double c[6], const CharPoly& p, double l, double vec[3],
                 double eigenvalues[3]) {
  const double a00 = c[0], a01 = c[1], a02 = c[2], a11 = c[3], a12 = c[4], a22 = c[5];
  const double trace = p.trace;
  double l1 = 0.0, l2 = 0.0, l3 = 0.0;
  if (trace > 0.0) {
    l = std::clamp(l, 0.0, 1.0 / 3.0);
    // The other two: l1 + l2 = 1 - l3 and l1 l2 = m2 - l3 (l1 + l2).
    const double sum = 1.0 - l;
    const double prod = std::max(0.0, p.m2 - l * sum);
    const double disc = std::sqrt(std::max(0.0, sum * sum - 4.0 * prod));
    l1 = 0.5 * (sum + disc) * trace;
    l2 = std::max(0.5 * (sum - disc), l) * trace;
    l3 = l * trace;
  }
  eigenvalues[0] = l1;
  eigenvalues[1] = l2;
  eigenvalues[2] = l3;

  // The eigenvector of l3 is orthogonal to the rows of A - l3 I: the longest cross product of
  // two rows. When l3 is repeated the rows are parallel; any vector orthogonal to them is one.
  const double r0[3] = {a00 - l3, a01, a02};
  const double r1[3] = {a01, a11 - l3, a12};
  const double r2[3] = {a02, a12, a22 - l3};
  auto cross = [](const double* a, const double* b, double* out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
    return out[0] * out[0] + out[1] * out[1] + out[2] * out[2];
  };
  double c01[3], c02[3], c12[3];
  const double n01 = cross(r0, r1, c01), n02 = cross(r0, r2, c02), n12 = cross(r1, r2, c12);
  const double* best = c01;
  double best_n = n01;
  if (n02 > best_n) best = c02, best_n = n02;
  if (n12 > best_n) best = c12, best_n = n12;
  const double row_scale = std::max({r0[0] * r0[0] + r0[1] * r0[1] + r0[2] * r0[2],
                                     r1[0] * r1[0] + r1[1] * r1[1] + r1[2] * r1[2],
                                     r2[0] * r2[0] + r2[1] * r2[1] + r2[2] * r2[2]});
  if (best_n > 1e-20 * row_scale * row_scale && best_n > 0.0) {
    const double s = 1.0 / std::sqrt(best_n);
    vec[0] = best[0] * s;
    vec[1] = best[1] * s;
    vec[2] = best[2] * s;
    return;
  }
  // Rank <= 1: orthogonal to the longest row (or any unit vector for a zero matrix).
  const double* r = r0;
  double rn = r0[0] * r0[0] + r0[1] * r0[1] + r0[2] * r0[2];
  const double rn1 = r1[0] * r1[0] + r1[1] * r1[1] + r1[2] * r1[2];
  const double rn2 = r2[0] * r2[0] + r2[1] * r2[1] + r2[2] * r2[2];
  if (rn1 > rn) r = r1, rn = rn1;
  if (rn2 > rn) r = r2, rn = rn2;
  if (!(rn > 0.0)) {
    vec[0] = 0.0;
    vec[1] = 0.0;
    vec[2] = 1.0;
    return;
  }
  // Cross with the axis least aligned with r.
  const double ax = std::fabs(r[0]), ay = std::fabs(r[1]), az = std::fabs(r[2]);
  const double e[3] = {ax <= ay && ax <= az ? 1.0 : 0.0, ay < ax && ay <= az ? 1.0 : 0.0,
                       az < ax && az < ay ? 1.0 : 0.0};
  double o[3];
  const double on = cross(r, e, o);
  const double s = 1.0 / std::sqrt(on);
  vec[0] = o[0] * s;
  vec[1] = o[1] * s;
  vec[2] = o[2] * s;
}

}  // namespace

void SmallestEigenvector(const double c[6], double vec[3], double eigenvalues[3]) {
  const CharPoly p = CharacteristicPolynomial(c);
  double l = 0.0;
  if (p.trace > 0.0) {
    for (int it = 0; it < kMaxNewtonSteps && NewtonStep(p, &l); ++it) {
    }
  }
  FinishEigen(c, p, l, vec, eigenvalues);
}

void SmallestEigenvectors(size_t n, const double (*c)[6], double (*vec)[3],
                          double (*eigenvalues)[3]) {
  // Groups of matrices iterate side by side: their Newton steps are independent chains of
  // dependent divisions, which the processor overlaps. Each matrix takes exactly the steps it
  // takes alone.
  constexpr size_t kGroup = 4;
  for (size_t g = 0; g < n; g += kGroup) {
    const size_t m = std::min(kGroup, n - g);
    CharPoly p[kGroup];
    double l[kGroup] = {0.0, 0.0, 0.0, 0.0};
    bool active[kGroup] = {false, false, false, false};
    for (size_t k = 0; k < m; ++k) {
      p[k] = CharacteristicPolynomial(c[g + k]);
      active[k] = p[k].trace > 0.0;
    }
    for (int it = 0; it < kMaxNewtonSteps; ++it) {
      bool any = false;
      for (size_t k = 0; k < m; ++k) {
        if (active[k]) active[k] = NewtonStep(p[k], &l[k]);
        any = any || active[k];
      }
      if (!any) break;
    }
    for (size_t k = 0; k < m; ++k)
      FinishEigen(c[g + k], p[k], l[k], vec[g + k], eigenvalues[g + k]);
  }
}

void MomentsCovariance(const double* m, double mean[3], double cov[6]) {
  const double inv = 1.0 / m[0];
  const double mx = m[1] * inv, my = m[2] * inv, mz = m[3] * inv;
  mean[0] = mx;
  mean[1] = my;
  mean[2] = mz;
  cov[0] = m[4] * inv - mx * mx;
  cov[1] = m[5] * inv - mx * my;
  cov[2] = m[6] * inv - mx * mz;
  cov[3] = m[7] * inv - my * my;
  cov[4] = m[8] * inv - my * mz;
  cov[5] = m[9] * inv - mz * mz;
}

void SummarizeMoments(const double* m, ShapeSummary* out) {
  double mean[3], cov[6];
  MomentsCovariance(m, mean, cov);
  const double mx = mean[0], my = mean[1], mz = mean[2];
  out->centroid =
      core::Vec3f{static_cast<float>(mx), static_cast<float>(my), static_cast<float>(mz)};
  for (int k = 0; k < 6; ++k) out->covariance[static_cast<size_t>(k)] = static_cast<float>(cov[k]);

  double nrm[3], l[3];
  SmallestEigenvector(cov, nrm, l);
  if (nrm[0] * mx + nrm[1] * my + nrm[2] * mz > 0.0) {
    nrm[0] = -nrm[0];
    nrm[1] = -nrm[1];
    nrm[2] = -nrm[2];
  }
  out->normal = core::Vec3f{static_cast<float>(nrm[0]), static_cast<float>(nrm[1]),
                            static_cast<float>(nrm[2])};
  out->eigenvalues =
      core::Vec3f{static_cast<float>(l[0]), static_cast<float>(l[1]), static_cast<float>(l[2])};
  const double total = l[0] + l[1] + l[2];
  out->curvature = total > 0.0 ? static_cast<float>(l[2] / total) : 0.f;
}

}  // namespace clutterseg::geometry
