#pragma once

// SSE2 helpers for arrays of core::Vec3f (x, y, z floats, 12 bytes each), four points at a
// time. Only defined where SSE2 is (every x86-64 build); callers keep a scalar path.

#if defined(__SSE2__)
#include <emmintrin.h>

#include "clutterseg/core/types.h"

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

/// Number of lanes set in a compare result (no popcnt instruction in the x86-64 baseline: a
/// table of the 16 four-bit counts in one constant).
inline uint32_t CountLanes(__m128 mask) {
  return static_cast<uint32_t>((0x4332322132212110u >> (4 * _mm_movemask_ps(mask))) & 0xfu);
}

/// The registers of four points given by their coordinates (lane k = point k): x, y, z as
/// given and the three raw vectors a, b, c that store them.
inline FourPoints MakeFourPoints(__m128 x, __m128 y, __m128 z) {
  FourPoints r;
  r.x = x;
  r.y = y;
  r.z = z;
  const __m128 xy01 = _mm_unpacklo_ps(x, y);                          // x0 y0 x1 y1
  const __m128 xy23 = _mm_unpackhi_ps(x, y);                          // x2 y2 x3 y3
  const __m128 z0x1 = _mm_shuffle_ps(z, x, _MM_SHUFFLE(1, 1, 0, 0));  // z0 z0 x1 x1
  const __m128 y1z1 = _mm_shuffle_ps(y, z, _MM_SHUFFLE(1, 1, 1, 1));  // y1 y1 z1 z1
  const __m128 z2x3 = _mm_shuffle_ps(z, x, _MM_SHUFFLE(3, 3, 2, 2));  // z2 z2 x3 x3
  const __m128 y3z3 = _mm_shuffle_ps(y, z, _MM_SHUFFLE(3, 3, 3, 3));  // y3 y3 z3 z3
  r.a = _mm_shuffle_ps(xy01, z0x1, _MM_SHUFFLE(2, 0, 1, 0));          // x0 y0 z0 x1
  r.b = _mm_shuffle_ps(y1z1, xy23, _MM_SHUFFLE(1, 0, 2, 0));          // y1 z1 x2 y2
  r.c = _mm_shuffle_ps(z2x3, y3z3, _MM_SHUFFLE(2, 0, 2, 0));          // z2 x3 y3 z3
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
