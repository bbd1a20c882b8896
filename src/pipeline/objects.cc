#include "clutterseg/pipeline/objects.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "clutterseg/core/scoped_timer.h"

namespace clutterseg::pipeline {
namespace {
constexpr float kFloatMax = std::numeric_limits<float>::max();
}  // namespace

struct ObjectExtractor::Accumulator {
  uint64_t n{0};
  double sum[3]{0.0, 0.0, 0.0};
  double sum_sq[6]{0.0, 0.0, 0.0, 0.0, 0.0, 0.0};  // xx, xy, xz, yy, yz, zz
  float min[3]{kFloatMax, kFloatMax, kFloatMax};
  float max[3]{-kFloatMax, -kFloatMax, -kFloatMax};
  uint64_t r{0}, g{0}, b{0};
  int umin{std::numeric_limits<int>::max()}, vmin{std::numeric_limits<int>::max()};
  int umax{-1}, vmax{-1};
};

// Principal axes (columns, largest variance first), centroid and the extents along the axes.
struct ObjectExtractor::Frame {
  Eigen::Matrix3f axes{Eigen::Matrix3f::Identity()};
  Eigen::Vector3f centroid{Eigen::Vector3f::Zero()};
  Eigen::Vector3f lo{Eigen::Vector3f::Constant(std::numeric_limits<float>::max())};
  Eigen::Vector3f hi{Eigen::Vector3f::Constant(std::numeric_limits<float>::lowest())};
};

// One object's gravity box: its points projected onto its plane, the hull's work.
struct ObjectExtractor::BoxWork {
  std::vector<float> projected;
  std::vector<float> hull_scratch;
  std::vector<std::pair<float, float>> hull_points;
  std::vector<std::pair<float, float>> hull;
};

namespace {
constexpr size_t kBandRows = 32;
// Columns of the projection whose extreme points make up the hull (see objects.h).
constexpr int kHullColumns = 512;

core::Vec3f ToVec(const Eigen::Vector3f& v) { return core::Vec3f{v.x(), v.y(), v.z()}; }

// A rectangle in the plane: unit axis (ax, ay) of its first side, the second side along
// (-ay, ax), centre (cx, cy), full side lengths len0 >= len1.
struct Rect2 {
  float ax{1.f}, ay{0.f};
  float cx{0.f}, cy{0.f};
  float len0{0.f}, len1{0.f};
};

double Cross(const std::pair<float, float>& o, const std::pair<float, float>& a,
             const std::pair<float, float>& b) {
  return (static_cast<double>(a.first) - o.first) * (static_cast<double>(b.second) - o.second) -
         (static_cast<double>(a.second) - o.second) * (static_cast<double>(b.first) - o.first);
}

// The minimum-area rectangle around `n` points (x, y interleaved at `xy`): the convex hull of
// the lowest and highest point of each of kHullColumns columns (Andrew's monotone chain), then
// for each hull edge the rectangle with a side along it (rotating calipers); the smallest wins
// (the first on a tie). `points`, `hull` and `columns` are reused work buffers. O(n) for n
// points, plus sorting the at most 2 * kHullColumns column extremes.
Rect2 MinAreaRect(const float* xy, size_t n, std::vector<std::pair<float, float>>* points,
                  std::vector<std::pair<float, float>>* hull, std::vector<float>* columns) {
  Rect2 r;
  if (n == 0) return r;
  float xmin = xy[0], xmax = xy[0];
  for (size_t i = 1; i < n; ++i) {
    xmin = std::min(xmin, xy[2 * i]);
    xmax = std::max(xmax, xy[2 * i]);
  }
  // Per column: x and y of its lowest point, x and y of its highest.
  columns->assign(4 * kHullColumns, std::numeric_limits<float>::quiet_NaN());
  const float scale = xmax > xmin ? static_cast<float>(kHullColumns) / (xmax - xmin) : 0.f;
  float* col = columns->data();
  for (size_t i = 0; i < n; ++i) {
    const float x = xy[2 * i], y = xy[2 * i + 1];
    const int c = std::min(kHullColumns - 1, static_cast<int>((x - xmin) * scale));
    float* e = col + 4 * c;
    if (!(y >= e[1])) {  // also the first point (NaN)
      e[0] = x;
      e[1] = y;
    }
    if (!(y <= e[3])) {
      e[2] = x;
      e[3] = y;
    }
  }
  points->clear();
  for (int c = 0; c < kHullColumns; ++c) {
    const float* e = col + 4 * c;
    if (std::isnan(e[1])) continue;
    points->emplace_back(e[0], e[1]);
    points->emplace_back(e[2], e[3]);
  }
  std::sort(points->begin(), points->end());
  points->erase(std::unique(points->begin(), points->end()), points->end());
  // Andrew's monotone chain: lower hull left to right, then upper hull right to left (CCW).
  hull->clear();
  const std::vector<std::pair<float, float>>& pts = *points;
  if (pts.size() < 3) {
    hull->assign(pts.begin(), pts.end());
  } else {
    for (size_t i = 0; i < pts.size(); ++i) {
      while (hull->size() >= 2 && Cross((*hull)[hull->size() - 2], hull->back(), pts[i]) <= 0.0) {
        hull->pop_back();
      }
      hull->push_back(pts[i]);
    }
    const size_t lower = hull->size() + 1;
    for (size_t i = pts.size() - 1; i-- > 0;) {
      while (hull->size() >= lower &&
             Cross((*hull)[hull->size() - 2], hull->back(), pts[i]) <= 0.0) {
        hull->pop_back();
      }
      hull->push_back(pts[i]);
    }
    hull->pop_back();  // the first point again
  }
  const std::vector<std::pair<float, float>>& h = *hull;
  if (h.size() == 1) {
    r.cx = h[0].first;
    r.cy = h[0].second;
    return r;
  }
  // Rotating calipers: for each edge a -> b (u along it, v = u turned left, into the hull),
  // the hull's extremes along u (lo, hi) and along v (far) only move forward around the hull.
  const size_t m = h.size();
  const size_t edges = m == 2 ? 1 : m;
  const auto along = [&h](size_t i, double ux, double uy) {
    return ux * h[i].first + uy * h[i].second;
  };
  size_t hi = 0, lo = 0, far = 0;
  double best = std::numeric_limits<double>::max();
  for (size_t i = 0; i < edges; ++i) {
    const auto& a = h[i];
    const auto& b = h[(i + 1) % m];
    double ux = static_cast<double>(b.first) - a.first,
           uy = static_cast<double>(b.second) - a.second;
    const double len = std::hypot(ux, uy);
    if (len == 0.0) continue;
    ux /= len;
    uy /= len;
    if (i == 0) {  // the first edge: full scans
      for (size_t k = 1; k < m; ++k) {
        if (along(k, ux, uy) > along(hi, ux, uy)) hi = k;
        if (along(k, ux, uy) < along(lo, ux, uy)) lo = k;
        if (along(k, -uy, ux) > along(far, -uy, ux)) far = k;
      }
    } else {
      for (size_t step = 0; step < m && along((hi + 1) % m, ux, uy) >= along(hi, ux, uy); ++step) {
        hi = (hi + 1) % m;
      }
      for (size_t step = 0; step < m && along((lo + 1) % m, ux, uy) <= along(lo, ux, uy); ++step) {
        lo = (lo + 1) % m;
      }
      for (size_t step = 0; step < m && along((far + 1) % m, -uy, ux) >= along(far, -uy, ux);
           ++step) {
        far = (far + 1) % m;
      }
    }
    const double u0 = along(lo, ux, uy), u1 = along(hi, ux, uy);
    const double v0 = along(i, -uy, ux), v1 = along(far, -uy, ux);
    const double area = (u1 - u0) * (v1 - v0);
    if (area < best) {
      best = area;
      const double mu = 0.5 * (u0 + u1), mv = 0.5 * (v0 + v1);
      r.cx = static_cast<float>(ux * mu - uy * mv);
      r.cy = static_cast<float>(uy * mu + ux * mv);
      r.ax = static_cast<float>(ux);
      r.ay = static_cast<float>(uy);
      r.len0 = static_cast<float>(u1 - u0);
      r.len1 = static_cast<float>(v1 - v0);
    }
  }
  if (r.len0 < r.len1) {  // the first axis along the longer side
    std::swap(r.len0, r.len1);
    const float ax = r.ax;
    r.ax = -r.ay;
    r.ay = ax;
  }
  return r;
}

}  // namespace

// Adds the valid points of pixels [u0, u1) of row v (one object's run; `xyz` and `rgba`
// point at the row's start, `rgba` null without colour) to `out`, point by point in pixel
// order, with the sums in locals along the run.
void ObjectExtractor::AccumulateRun(const core::Vec3f* xyz, const uint32_t* rgba, int u0, int u1,
                                    int v, Accumulator* out) {
  Accumulator& a = *out;
  uint64_t n = a.n;
  double sx = a.sum[0], sy = a.sum[1], sz = a.sum[2];
  double sxx = a.sum_sq[0], sxy = a.sum_sq[1], sxz = a.sum_sq[2];
  double syy = a.sum_sq[3], syz = a.sum_sq[4], szz = a.sum_sq[5];
  float x0 = a.min[0], y0 = a.min[1], z0 = a.min[2];
  float x1 = a.max[0], y1 = a.max[1], z1 = a.max[2];
  uint64_t r = a.r, g = a.g, b = a.b;
  int first = -1, last = -1;
  for (int u = u0; u < u1; ++u) {
    const core::Vec3f& p = xyz[u];
    if (!core::IsValid(p)) continue;
    if (first < 0) first = u;
    last = u;
    const double x = p.x, y = p.y, z = p.z;
    ++n;
    sx += x;
    sy += y;
    sz += z;
    sxx += x * x;
    sxy += x * y;
    sxz += x * z;
    syy += y * y;
    syz += y * z;
    szz += z * z;
    x0 = std::min(x0, p.x);
    y0 = std::min(y0, p.y);
    z0 = std::min(z0, p.z);
    x1 = std::max(x1, p.x);
    y1 = std::max(y1, p.y);
    z1 = std::max(z1, p.z);
    if (rgba != nullptr) {
      const core::Rgb8 c = core::UnpackRgba(rgba[u]);
      r += c.r;
      g += c.g;
      b += c.b;
    }
  }
  if (first < 0) return;
  a.n = n;
  a.sum[0] = sx;
  a.sum[1] = sy;
  a.sum[2] = sz;
  a.sum_sq[0] = sxx;
  a.sum_sq[1] = sxy;
  a.sum_sq[2] = sxz;
  a.sum_sq[3] = syy;
  a.sum_sq[4] = syz;
  a.sum_sq[5] = szz;
  a.min[0] = x0;
  a.min[1] = y0;
  a.min[2] = z0;
  a.max[0] = x1;
  a.max[1] = y1;
  a.max[2] = z1;
  a.r = r;
  a.g = g;
  a.b = b;
  a.umin = std::min(a.umin, first);
  a.umax = std::max(a.umax, last);
  a.vmin = std::min(a.vmin, v);
  a.vmax = std::max(a.vmax, v);
}

void ObjectExtractor::SupportAndGravityBox(const std::vector<Plane>& planes, uint32_t k,
                                           BoxWork* work, Object* o) const {
  const core::Vec3f* points = points_.data() + object_first_[k];
  const size_t n = object_first_[k + 1] - object_first_[k];
  if (n == 0) return;
  const Eigen::Vector3f centroid(o->centroid.x, o->centroid.y, o->centroid.z);
  // Support plane: a support plane the object stands on has the object on its camera side
  // (positive signed distance of the centroid, normals point to the camera) and its lowest
  // point nearly touches it (within 0.1 m). Pick the one nearest to the lowest point.
  const Plane* support = nullptr;
  Eigen::Vector3f up = Eigen::Vector3f::Zero();
  float d = 0.f;
  float best = std::numeric_limits<float>::max();
  float bottom = 0.f, top = 0.f;
  for (const Plane& pl : planes) {
    if (!pl.is_support) continue;
    const Eigen::Vector3f normal(pl.normal.x, pl.normal.y, pl.normal.z);
    const float norm = normal.norm();
    if (!(norm > 0.f)) continue;
    const Eigen::Vector3f unit = normal / norm;
    const float plane_d = pl.d / norm;
    if (unit.dot(centroid) + plane_d <= 0.f) continue;  // the object is behind the plane
    float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
    for (size_t i = 0; i < n; ++i) {
      const float h =
          unit.x() * points[i].x + unit.y() * points[i].y + unit.z() * points[i].z + plane_d;
      lo = std::min(lo, h);
      hi = std::max(hi, h);
    }
    if (std::abs(lo) < best && std::abs(lo) < 0.1f) {
      best = std::abs(lo);
      support = &pl;
      up = unit;
      d = plane_d;
      bottom = lo;
      top = hi;
    }
  }
  if (support == nullptr) return;
  o->support_plane_id = static_cast<int32_t>(support->id);
  // The plane frame: the centroid projected onto the plane, e1 the camera's x axis in the plane
  // (its z axis for a plane facing along x), e2 = up x e1.
  const Eigen::Vector3f origin = centroid - (up.dot(centroid) + d) * up;
  const Eigen::Vector3f ref =
      std::abs(up.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f e1 = (ref - up.dot(ref) * up).normalized();
  const Eigen::Vector3f e2 = up.cross(e1).normalized();
  std::vector<float>& projected = work->projected;
  projected.resize(2 * n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f r = Eigen::Vector3f(points[i].x, points[i].y, points[i].z) - origin;
    projected[2 * i] = e1.dot(r);
    projected[2 * i + 1] = e2.dot(r);
  }
  const Rect2 rect =
      MinAreaRect(projected.data(), n, &work->hull_points, &work->hull, &work->hull_scratch);
  // A deterministic sign: the first axis along +e1 (or +e2).
  float ax = rect.ax, ay = rect.ay;
  if (ax < 0.f || (ax == 0.f && ay < 0.f)) {
    ax = -ax;
    ay = -ay;
  }
  const Eigen::Vector3f a0 = (ax * e1 + ay * e2).normalized();
  const Eigen::Vector3f a1 = up.cross(a0).normalized();
  const float height = std::max(top, 0.f);
  o->has_gravity_box = true;
  o->gbox_axes[0] = ToVec(a0);
  o->gbox_axes[1] = ToVec(a1);
  o->gbox_axes[2] = ToVec(up);
  o->gbox_center = ToVec(origin + rect.cx * e1 + rect.cy * e2 + 0.5f * height * up);
  o->gbox_extents = core::Vec3f{rect.len0, rect.len1, height};
  o->height_m = top;
  o->bottom_m = bottom;
}

ObjectExtractor::ObjectExtractor(core::ThreadPool* pool) : pool_(pool) {}
ObjectExtractor::~ObjectExtractor() = default;

void ObjectExtractor::Compute(const core::PointCloudView& cloud, SegmentationResult* result) {
  const core::ScopedTimer timer(&result->times[Stage::kObjects]);
  core::ThreadPool* const pool = pool_;
  const core::LabelImage& labels = result->labels;
  const std::vector<Plane>& planes = result->planes;
  std::vector<Object>* const objects = &result->objects;
  const auto num_objects = static_cast<uint32_t>(objects->size());
  if (num_objects == 0) return;
  const bool color = cloud.has_color();
  const int w = labels.width;
  const int h = w > 0 ? static_cast<int>(labels.data.size() / static_cast<size_t>(w)) : 0;
  // Bands of whole rows, fixed whatever the pool: each accumulates on its own, and the bands
  // are added up in order, so the sums do not depend on the thread count.
  const size_t rows = static_cast<size_t>(h);
  const size_t num_bands = core::ThreadPool::NumChunks(rows, kBandRows);
  band_acc_.assign(num_bands * num_objects, Accumulator{});
  core::ForChunks(pool, rows, kBandRows, [&](size_t row_begin, size_t row_end) {
    Accumulator* acc = &band_acc_[(row_begin / kBandRows) * num_objects];
    const int width = w;
    const uint32_t count = num_objects;
    const uint32_t* label = labels.data.data();
    const core::Vec3f* xyz = cloud.xyz.data();
    const uint32_t* rgba = color ? cloud.rgba.data() : nullptr;
    for (size_t v = row_begin; v < row_end; ++v) {
      const size_t row = v * static_cast<size_t>(width);
      // Runs of one label: an object's accumulator stays in registers along its run (a store
      // per point would chain every point's sums through memory). The points are still added
      // one by one in pixel order.
      for (int u = 0; u < width;) {
        const uint32_t l = label[row + static_cast<size_t>(u)];
        int run_end = u + 1;
        while (run_end < width && label[row + static_cast<size_t>(run_end)] == l) ++run_end;
        if (l - 1 < count) {  // 0 (no object) wraps around
          AccumulateRun(xyz + row, rgba != nullptr ? rgba + row : nullptr, u, run_end,
                        static_cast<int>(v), &acc[l - 1]);
        }
        u = run_end;
      }
    }
  });
  acc_.assign(num_objects, Accumulator{});
  std::vector<Accumulator>& acc = acc_;
  for (size_t b = 0; b < num_bands; ++b) {
    for (uint32_t k = 0; k < num_objects; ++k) {
      const Accumulator& x = band_acc_[b * num_objects + k];
      if (x.n == 0) continue;
      Accumulator& a = acc[k];
      a.n += x.n;
      for (int j = 0; j < 3; ++j) a.sum[j] += x.sum[j];
      for (int j = 0; j < 6; ++j) a.sum_sq[j] += x.sum_sq[j];
      for (int j = 0; j < 3; ++j) {
        a.min[j] = std::min(a.min[j], x.min[j]);
        a.max[j] = std::max(a.max[j], x.max[j]);
      }
      a.r += x.r;
      a.g += x.g;
      a.b += x.b;
      a.umin = std::min(a.umin, x.umin);
      a.umax = std::max(a.umax, x.umax);
      a.vmin = std::min(a.vmin, x.vmin);
      a.vmax = std::max(a.vmax, x.vmax);
    }
  }

  // Oriented boxes need the extents along the principal axes: a second pass.
  frames_.assign(num_objects, Frame{});
  for (uint32_t k = 0; k < num_objects; ++k) {
    const Accumulator& a = acc[k];
    if (a.n == 0) continue;
    const Eigen::Vector3d c =
        Eigen::Vector3d(a.sum[0], a.sum[1], a.sum[2]) / static_cast<double>(a.n);
    Eigen::Matrix3d sum_sq;
    sum_sq << a.sum_sq[0], a.sum_sq[1], a.sum_sq[2], a.sum_sq[1], a.sum_sq[3], a.sum_sq[4],
        a.sum_sq[2], a.sum_sq[4], a.sum_sq[5];
    Eigen::Matrix3d cov = sum_sq / static_cast<double>(a.n) - c * c.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(cov);
    Eigen::Matrix3f ax;
    // Columns: largest variance first.
    ax.col(0) = es.eigenvectors().col(2).cast<float>().normalized();
    ax.col(1) = es.eigenvectors().col(1).cast<float>().normalized();
    // Deterministic signs: first axis points to +x (or +y), second towards the camera side.
    if (ax(0, 0) < 0.f || (ax(0, 0) == 0.f && ax(1, 0) < 0.f)) ax.col(0) = -ax.col(0);
    if (ax(1, 1) < 0.f || (ax(1, 1) == 0.f && ax(2, 1) < 0.f)) ax.col(1) = -ax.col(1);
    ax.col(2) = ax.col(0).cross(ax.col(1)).normalized();
    frames_[k].axes = ax;
    frames_[k].centroid = c.cast<float>();
  }
  // Where each object's points go in points_ (per object, per band in band order).
  point_start_.assign(num_bands * num_objects, 0);
  object_first_.assign(num_objects + 1, 0);
  size_t num_points = 0;
  for (uint32_t k = 0; k < num_objects; ++k) {
    object_first_[k] = num_points;
    for (size_t b = 0; b < num_bands; ++b) {
      point_start_[b * num_objects + k] = num_points;
      num_points += band_acc_[b * num_objects + k].n;
    }
  }
  object_first_[num_objects] = num_points;
  points_.resize(num_points);

  // Extents: minima and maxima, exact in any order; each object's points copied into points_,
  // each band into its own slots (the support planes and gravity boxes read them).
  band_frames_.assign(num_bands * num_objects, Frame{});
  core::ForChunks(pool, rows, kBandRows, [&](size_t row_begin, size_t row_end) {
    const size_t band = row_begin / kBandRows;
    Frame* local = &band_frames_[band * num_objects];
    const uint32_t count = num_objects;
    const uint32_t* label = labels.data.data();
    const core::Vec3f* xyz = cloud.xyz.data();
    const size_t end = row_end * static_cast<size_t>(w);
    for (size_t i = row_begin * static_cast<size_t>(w); i < end;) {
      const uint32_t l = label[i];
      size_t run_end = i + 1;
      while (run_end < end && label[run_end] == l) ++run_end;
      if (l - 1 < count) {
        const Frame& f = frames_[l - 1];
        const Eigen::Matrix3f axes_t = f.axes.transpose();
        const Eigen::Vector3f centroid = f.centroid;
        Eigen::Vector3f lo = local[l - 1].lo, hi = local[l - 1].hi;
        // One pass over the run: the extents and the copy of its valid points.
        size_t next = point_start_[band * count + (l - 1)];
        core::Vec3f* const points = points_.data();
        for (size_t k = i; k < run_end; ++k) {
          const core::Vec3f p = xyz[k];
          if (!core::IsValid(p)) continue;
          const Eigen::Vector3f q = axes_t * (Eigen::Vector3f(p.x, p.y, p.z) - centroid);
          lo = lo.cwiseMin(q);
          hi = hi.cwiseMax(q);
          points[next++] = p;
        }
        local[l - 1].lo = lo;
        local[l - 1].hi = hi;
        point_start_[band * count + (l - 1)] = next;
      }
      i = run_end;
    }
  });
  for (size_t b = 0; b < num_bands; ++b) {
    for (uint32_t k = 0; k < num_objects; ++k) {
      const Frame& box = band_frames_[b * num_objects + k];
      frames_[k].lo = frames_[k].lo.cwiseMin(box.lo);
      frames_[k].hi = frames_[k].hi.cwiseMax(box.hi);
    }
  }

  for (uint32_t k = 0; k < num_objects; ++k) {
    const Accumulator& a = acc[k];
    const Frame& f = frames_[k];
    Object& o = (*objects)[k];
    o = Object{};
    o.id = k + 1;
    o.num_points = static_cast<uint32_t>(a.n);
    if (a.n == 0) continue;
    o.centroid = ToVec(f.centroid);
    o.aabb_min = core::Vec3f{a.min[0], a.min[1], a.min[2]};
    o.aabb_max = core::Vec3f{a.max[0], a.max[1], a.max[2]};
    o.obb_center = ToVec(f.centroid + f.axes * (0.5f * (f.lo + f.hi)));
    for (int j = 0; j < 3; ++j) o.obb_axes[j] = ToVec(f.axes.col(j));
    o.obb_extents = ToVec(f.hi - f.lo);
    o.mean_color = core::Rgb8{static_cast<uint8_t>(a.r / a.n), static_cast<uint8_t>(a.g / a.n),
                              static_cast<uint8_t>(a.b / a.n)};
    o.pixel_min_u = a.umin;
    o.pixel_min_v = a.vmin;
    o.pixel_max_u = a.umax;
    o.pixel_max_v = a.vmax;
    // Confidence: small objects and objects with few points relative to their box are less
    // certain; a simple monotone score in 0..1.
    o.confidence = std::clamp(static_cast<float>(a.n) / 2000.f, 0.2f, 1.f);
  }
  // The support planes and gravity boxes: one object per task, each with its own buffers.
  if (box_work_.size() < num_objects) box_work_.resize(num_objects);
  core::ForChunks(pool, num_objects, 1, [&](size_t k0, size_t k1) {
    for (size_t k = k0; k < k1; ++k) {
      Object& o = (*objects)[k];
      if (o.num_points == 0) continue;
      SupportAndGravityBox(planes, static_cast<uint32_t>(k), &box_work_[k], &o);
    }
  });
}

}  // namespace clutterseg::pipeline
