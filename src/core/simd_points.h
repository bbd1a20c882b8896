#pragma once

// SSE2 helpers for arrays of core::Vec3f (x, y, z floats, 12 bytes each), four points at a
// time. Only defined where SSE2 is (every x86-64 build); callers keep a scalar path.

#if defined(__SSE2__)
#include <emmintrin.h>

#include "core/types.h"

namespace clutterseg::core {

/// The registers of four consecutive points: x, y and z of points 0..3 in lanes 0..3, and the
/// three raw loads (a = x0 y0 z0 x1, b = y1 z1 x2 y2, c = z2 x3 y3 z3) to store them back.
struct FourPoints {
  __m128 a, b, c;
  __m128 x, y, z;
};

/// Loads points p[0..3] (12 floats from &p[0].x, unaligned).
inline FourPoints LoadFourPoints(const Vec3f* p) {
  const float* f = &p->x;
  FourPoints r;
  r.a = _mm_loadu_ps(f);
  r.b = _mm_loadu_ps(f + 4);
  r.c = _mm_loadu_ps(f + 8);
  r.x = _mm_shuffle_ps(r.a, _mm_shuffle_ps(r.b, r.c, _MM_SHUFFLE(1, 1, 2, 2)),
                       _MM_SHUFFLE(2, 0, 3, 0));
  r.y = _mm_shuffle_ps(_mm_shuffle_ps(r.a, r.b, _MM_SHUFFLE(0, 0, 1, 1)),
                       _mm_shuffle_ps(r.b, r.c, _MM_SHUFFLE(2, 2, 3, 3)), _MM_SHUFFLE(2, 0, 2, 0));
  r.z = _mm_shuffle_ps(_mm_shuffle_ps(r.a, r.b, _MM_SHUFFLE(1, 1, 2, 2)),
                       _mm_shuffle_ps(r.c, r.c, _MM_SHUFFLE(3, 3, 0, 0)), _MM_SHUFFLE(2, 0, 2, 0));
  return r;
}

/// Stores the four points of `pts` to p[0..3], each replaced by `fill` where its lane of
/// `keep` (one lane per point, all ones or all zeros) is zero.
inline void StoreFourPointsWhere(__m128 keep, const FourPoints& pts, __m128 fill, Vec3f* p) {
  // The per-point lanes spread over each point's three floats, in the layout of a, b, c.
  const __m128 ka = _mm_shuffle_ps(keep, keep, _MM_SHUFFLE(1, 0, 0, 0));
  const __m128 kb = _mm_shuffle_ps(keep, keep, _MM_SHUFFLE(2, 2, 1, 1));
  const __m128 kc = _mm_shuffle_ps(keep, keep, _MM_SHUFFLE(3, 3, 3, 2));
  float* f = &p->x;
  _mm_storeu_ps(f, _mm_or_ps(_mm_and_ps(ka, pts.a), _mm_andnot_ps(ka, fill)));
  _mm_storeu_ps(f + 4, _mm_or_ps(_mm_and_ps(kb, pts.b), _mm_andnot_ps(kb, fill)));
  _mm_storeu_ps(f + 8, _mm_or_ps(_mm_and_ps(kc, pts.c), _mm_andnot_ps(kc, fill)));
}

}  // namespace clutterseg::core

#endif  // __SSE2__
