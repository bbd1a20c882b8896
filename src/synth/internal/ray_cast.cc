#include "clutterseg/synth/internal/ray_cast.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace clutterseg::synth::internal {
namespace {

// Keeps the nearest candidate root inside (t_min, best).
struct Nearest {
  double t_min;
  double best;
  Vec3 normal;
  bool hit{false};

  void Offer(double t, const Vec3& n) {
    if (t > t_min && t < best) {
      best = t;
      normal = n;
      hit = true;
    }
  }
};

// Real roots of a t^2 + b t + c = 0 in ascending order; returns their count.
int SolveQuadratic(double a, double b, double c, double* r0, double* r1) {
  if (std::abs(a) < 1e-14) {
    if (std::abs(b) < 1e-14) return 0;
    *r0 = -c / b;
    return 1;
  }
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) return 0;
  const double s = std::sqrt(disc);
  // Numerically stable form avoiding cancellation.
  const double q = -0.5 * (b + (b >= 0.0 ? s : -s));
  double x0 = q / a;
  double x1 = q != 0.0 ? c / q : x0;
  if (x0 > x1) std::swap(x0, x1);
  *r0 = x0;
  *r1 = x1;
  return 2;
}

void BoxHit(const Vec3& o, const Vec3& d, const Vec3& h, Nearest* n) {
  const double oo[3] = {o.x, o.y, o.z};
  const double dd[3] = {d.x, d.y, d.z};
  const double hh[3] = {h.x, h.y, h.z};
  double t_near = -std::numeric_limits<double>::infinity();
  double t_far = std::numeric_limits<double>::infinity();
  int axis_near = -1;
  int axis_far = -1;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(dd[i]) < 1e-15) {
      if (std::abs(oo[i]) > hh[i]) return;
      continue;
    }
    const double inv = 1.0 / dd[i];
    double t1 = (-hh[i] - oo[i]) * inv;
    double t2 = (hh[i] - oo[i]) * inv;
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > t_near) {
      t_near = t1;
      axis_near = i;
    }
    if (t2 < t_far) {
      t_far = t2;
      axis_far = i;
    }
  }
  if (t_near > t_far || axis_near < 0) return;
  auto face_normal = [&](int axis, double sign) {
    Vec3 v;
    (axis == 0 ? v.x : axis == 1 ? v.y : v.z) = sign;
    return v;
  };
  // Entering face normal points against the ray; the exit face normal along it.
  n->Offer(t_near, face_normal(axis_near, dd[axis_near] > 0.0 ? -1.0 : 1.0));
  if (!n->hit) n->Offer(t_far, face_normal(axis_far, dd[axis_far] > 0.0 ? 1.0 : -1.0));
}

// Cylinder or frustum along z with radius r(z) = r0 + k (z + hz), |z| <= hz.
void ConeHit(const Vec3& o, const Vec3& d, double r0, double r1, double hz, bool cap_bottom,
             bool cap_top, Nearest* n) {
  const double k = (r1 - r0) / (2.0 * hz);
  const double a_lin = r0 + k * (o.z + hz);  // r at t = 0
  const double b_lin = k * d.z;              // dr/dt
  const double a = d.x * d.x + d.y * d.y - b_lin * b_lin;
  const double b = 2.0 * (o.x * d.x + o.y * d.y - a_lin * b_lin);
  const double c = o.x * o.x + o.y * o.y - a_lin * a_lin;
  double roots[2];
  const int count = SolveQuadratic(a, b, c, &roots[0], &roots[1]);
  for (int i = 0; i < count; ++i) {
    const double t = roots[i];
    const double z = o.z + t * d.z;
    if (std::abs(z) > hz) continue;
    const double r = a_lin + b_lin * t;
    if (r < 0.0) continue;  // the mirrored nappe of the cone
    const double x = o.x + t * d.x;
    const double y = o.y + t * d.y;
    n->Offer(t, Normalized(Vec3{x, y, -r * k}));
  }
  if (std::abs(d.z) > 1e-15) {
    if (cap_bottom) {
      const double t = (-hz - o.z) / d.z;
      const double x = o.x + t * d.x;
      const double y = o.y + t * d.y;
      if (x * x + y * y <= r0 * r0) n->Offer(t, Vec3{0.0, 0.0, -1.0});
    }
    if (cap_top) {
      const double t = (hz - o.z) / d.z;
      const double x = o.x + t * d.x;
      const double y = o.y + t * d.y;
      if (x * x + y * y <= r1 * r1) n->Offer(t, Vec3{0.0, 0.0, 1.0});
    }
  }
}

void SphereHit(const Vec3& o, const Vec3& d, double r, bool lower_half_only, Nearest* n) {
  double roots[2];
  const int count =
      SolveQuadratic(Dot(d, d), 2.0 * Dot(o, d), Dot(o, o) - r * r, &roots[0], &roots[1]);
  if (count < 2) return;
  for (double t : roots) {
    const Vec3 p = o + t * d;
    if (lower_half_only && p.z > 0.0) continue;
    n->Offer(t, (1.0 / r) * p);
  }
}

}  // namespace

PreparedPrimitive Prepare(const Primitive& primitive, uint32_t index) {
  PreparedPrimitive p;
  p.kind = primitive.kind;
  p.pose = primitive.pose;
  p.cap_bottom = primitive.cap_bottom;
  p.cap_top = primitive.cap_top;
  p.index = index;
  p.bound_center = primitive.pose.translation;
  const Vec3& s = primitive.size_m;
  switch (primitive.kind) {
    case PrimitiveKind::kBox:
      p.half_size = 0.5 * s;
      p.bound_radius = Norm(p.half_size);
      break;
    case PrimitiveKind::kCylinder:
      p.half_size = {s.x, s.x, 0.5 * s.z};
      p.bound_radius = std::hypot(s.x, 0.5 * s.z);
      break;
    case PrimitiveKind::kFrustum:
      p.half_size = {s.x, s.y, 0.5 * s.z};
      p.bound_radius = std::hypot(std::max(s.x, s.y), 0.5 * s.z);
      break;
    case PrimitiveKind::kSphere:
    case PrimitiveKind::kHemisphereShell:
      p.half_size = {s.x, s.x, s.x};
      p.bound_radius = s.x;
      break;
    case PrimitiveKind::kPlane:
      p.bounded = false;
      break;
  }
  p.box_half = p.half_size;
  if (p.kind == PrimitiveKind::kFrustum) {
    p.box_half.x = p.box_half.y = std::max(p.half_size.x, p.half_size.y);
  }
  return p;
}

bool Intersect(const PreparedPrimitive& p, const Vec3& origin, const Vec3& dir, double t_min,
               double t_max, double* t, Vec3* normal) {
  if (p.bounded) {
    // Reject rays that pass outside the bounding sphere.
    const Vec3 oc = p.bound_center - origin;
    const Vec3 cr = Cross(oc, dir);
    const double r = p.bound_radius * (1.0 + 1e-9) + 1e-9;
    if (Dot(cr, cr) > r * r * Dot(dir, dir)) return false;
  }
  const Vec3 o = p.pose.InverseApply(origin);
  const Vec3 d = p.pose.InverseRotate(dir);
  Nearest n{t_min, t_max, {}};
  switch (p.kind) {
    case PrimitiveKind::kBox:
      BoxHit(o, d, p.half_size, &n);
      break;
    case PrimitiveKind::kCylinder:
      ConeHit(o, d, p.half_size.x, p.half_size.x, p.half_size.z, p.cap_bottom, p.cap_top, &n);
      break;
    case PrimitiveKind::kFrustum:
      ConeHit(o, d, p.half_size.x, p.half_size.y, p.half_size.z, p.cap_bottom, p.cap_top, &n);
      break;
    case PrimitiveKind::kSphere:
      SphereHit(o, d, p.half_size.x, false, &n);
      break;
    case PrimitiveKind::kHemisphereShell:
      SphereHit(o, d, p.half_size.x, true, &n);
      break;
    case PrimitiveKind::kPlane:
      if (std::abs(d.z) > 1e-15) n.Offer(-o.z / d.z, Vec3{0.0, 0.0, 1.0});
      break;
  }
  if (!n.hit) return false;
  *t = n.best;
  *normal = p.pose.Rotate(n.normal);
  return true;
}

bool ProjectBound(const PreparedPrimitive& p, const Pose& eye_pose, double fx, double fy, double cx,
                  double cy, double* u0, double* u1, double* v0, double* v1) {
  if (!p.bounded) return false;
  // The primitive lies inside its local bounding box; the box's image is the convex hull of
  // its corner images when every corner is in front of the eye.
  *u0 = *v0 = std::numeric_limits<double>::infinity();
  *u1 = *v1 = -std::numeric_limits<double>::infinity();
  const Vec3& h = p.box_half;
  for (int i = 0; i < 8; ++i) {
    const Vec3 local{(i & 1) ? h.x : -h.x, (i & 2) ? h.y : -h.y, (i & 4) ? h.z : -h.z};
    const Vec3 c = eye_pose.InverseApply(p.pose.Apply(local));
    if (c.z <= 1e-3) return false;
    const double u = fx * c.x / c.z + cx;
    const double v = fy * c.y / c.z + cy;
    *u0 = std::min(*u0, u);
    *u1 = std::max(*u1, u);
    *v0 = std::min(*v0, v);
    *v1 = std::max(*v1, v);
  }
  return true;
}

void TileBins::Build(const std::vector<PreparedPrimitive>& prims, const Pose& eye_pose, double fx,
                     double fy, double cx, double cy, int width, int height, int margin_px) {
  origin_px_ = -margin_px;
  tiles_x_ = (width + 2 * margin_px + kTilePx - 1) / kTilePx;
  tiles_y_ = (height + 2 * margin_px + kTilePx - 1) / kTilePx;
  const size_t num_tiles = static_cast<size_t>(tiles_x_) * tiles_y_;
  all_.resize(prims.size());
  for (size_t i = 0; i < prims.size(); ++i) all_[i] = static_cast<uint32_t>(i);

  // Tile range per primitive, then a counting pass and a fill pass (CSR).
  struct Range {
    int tx0, tx1, ty0, ty1;
  };
  std::vector<Range> ranges(prims.size());
  for (size_t i = 0; i < prims.size(); ++i) {
    double u0, u1, v0, v1;
    Range& r = ranges[i];
    if (!ProjectBound(prims[i], eye_pose, fx, fy, cx, cy, &u0, &u1, &v0, &v1)) {
      r = {0, tiles_x_ - 1, 0, tiles_y_ - 1};
      continue;
    }
    auto tile_of = [&](double px, int count) {
      const double t = std::floor((px - origin_px_) / kTilePx);
      return static_cast<int>(std::clamp(t, -1.0, static_cast<double>(count)));
    };
    r = {tile_of(u0 - 1.0, tiles_x_), tile_of(u1 + 1.0, tiles_x_), tile_of(v0 - 1.0, tiles_y_),
         tile_of(v1 + 1.0, tiles_y_)};
    r.tx0 = std::max(r.tx0, 0);
    r.ty0 = std::max(r.ty0, 0);
    r.tx1 = std::min(r.tx1, tiles_x_ - 1);
    r.ty1 = std::min(r.ty1, tiles_y_ - 1);
  }
  offsets_.assign(num_tiles + 1, 0);
  for (const Range& r : ranges) {
    for (int ty = r.ty0; ty <= r.ty1; ++ty) {
      for (int tx = r.tx0; tx <= r.tx1; ++tx)
        ++offsets_[static_cast<size_t>(ty) * tiles_x_ + tx + 1];
    }
  }
  for (size_t i = 0; i < num_tiles; ++i) offsets_[i + 1] += offsets_[i];
  items_.resize(offsets_[num_tiles]);
  std::vector<uint32_t> fill(offsets_.begin(), offsets_.end() - 1);
  for (size_t i = 0; i < ranges.size(); ++i) {
    const Range& r = ranges[i];
    for (int ty = r.ty0; ty <= r.ty1; ++ty) {
      for (int tx = r.tx0; tx <= r.tx1; ++tx) {
        items_[fill[static_cast<size_t>(ty) * tiles_x_ + tx]++] = static_cast<uint32_t>(i);
      }
    }
  }
}

void TileBins::Candidates(double u, double v, const uint32_t** begin, const uint32_t** end) const {
  // NaN or out-of-grid positions fall back to the full list.
  const double fx = (u - origin_px_) * (1.0 / kTilePx);
  const double fy = (v - origin_px_) * (1.0 / kTilePx);
  if (!(fx >= 0.0 && fy >= 0.0 && fx < tiles_x_ && fy < tiles_y_)) {
    *begin = all_.data();
    *end = all_.data() + all_.size();
    return;
  }
  const size_t tile = static_cast<size_t>(fy) * tiles_x_ + static_cast<size_t>(fx);
  *begin = items_.data() + offsets_[tile];
  *end = items_.data() + offsets_[tile + 1];
}

}  // namespace clutterseg::synth::internal
