#include "clutterseg/pipeline/objects.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include "clutterseg/core/scoped_timer.h"

namespace clutterseg::pipeline {
struct ObjectExtractor::Accumulator {
  uint64_t n{0};
  Eigen::Vector3d sum{Eigen::Vector3d::Zero()};
  Eigen::Matrix3d sum_sq{Eigen::Matrix3d::Zero()};
  Eigen::Vector3f min{Eigen::Vector3f::Constant(std::numeric_limits<float>::max())};
  Eigen::Vector3f max{Eigen::Vector3f::Constant(std::numeric_limits<float>::lowest())};
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

namespace {
constexpr size_t kBandRows = 32;

core::Vec3f ToVec(const Eigen::Vector3f& v) { return core::Vec3f{v.x(), v.y(), v.z()}; }

}  // namespace

ObjectExtractor::ObjectExtractor(core::ThreadPool* pool) : pool_(pool) {}
ObjectExtractor::~ObjectExtractor() = default;

void ObjectExtractor::Compute(const core::PointCloud& cloud, SegmentationResult* result) {
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
    // Locals: the accumulators' stores would otherwise force reloads of what the lambda
    // captures by reference.
    Accumulator* acc = &band_acc_[(row_begin / kBandRows) * num_objects];
    const int width = w;
    const uint32_t count = num_objects;
    const uint32_t* label = labels.data.data();
    const core::Vec3f* xyz = cloud.xyz.data();
    for (size_t v = row_begin; v < row_end; ++v) {
      const size_t row = v * static_cast<size_t>(width);
      for (int u = 0; u < width; ++u) {
        const size_t i = row + static_cast<size_t>(u);
        const uint32_t l = label[i];
        if (l - 1 >= count) continue;  // 0 (no object) wraps around
        const core::Vec3f& p = xyz[i];
        if (!core::IsValid(p)) continue;
        Accumulator& a = acc[l - 1];
        const Eigen::Vector3d q(p.x, p.y, p.z);
        a.n++;
        a.sum += q;
        a.sum_sq.noalias() += q * q.transpose();
        const Eigen::Vector3f pf(p.x, p.y, p.z);
        a.min = a.min.cwiseMin(pf);
        a.max = a.max.cwiseMax(pf);
        if (color) {
          const core::Rgb8 c = core::UnpackRgba(cloud.rgba[i]);
          a.r += c.r;
          a.g += c.g;
          a.b += c.b;
        }
        a.umin = std::min(a.umin, u);
        a.umax = std::max(a.umax, u);
        a.vmin = std::min(a.vmin, static_cast<int>(v));
        a.vmax = std::max(a.vmax, static_cast<int>(v));
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
      a.sum += x.sum;
      a.sum_sq += x.sum_sq;
      a.min = a.min.cwiseMin(x.min);
      a.max = a.max.cwiseMax(x.max);
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
    const Eigen::Vector3d c = a.sum / static_cast<double>(a.n);
    Eigen::Matrix3d cov = a.sum_sq / static_cast<double>(a.n) - c * c.transpose();
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
  // Extents: minima and maxima, exact in any order.
  band_frames_.assign(num_bands * num_objects, Frame{});
  core::ForChunks(pool, rows, kBandRows, [&](size_t row_begin, size_t row_end) {
    Frame* local = &band_frames_[(row_begin / kBandRows) * num_objects];
    const uint32_t count = num_objects;
    const uint32_t* label = labels.data.data();
    const core::Vec3f* xyz = cloud.xyz.data();
    const size_t end = row_end * static_cast<size_t>(w);
    for (size_t i = row_begin * static_cast<size_t>(w); i < end; ++i) {
      const uint32_t l = label[i];
      if (l - 1 >= count) continue;
      const core::Vec3f& p = xyz[i];
      if (!core::IsValid(p)) continue;
      const Frame& f = frames_[l - 1];
      const Eigen::Vector3f q = f.axes.transpose() * (Eigen::Vector3f(p.x, p.y, p.z) - f.centroid);
      Frame& box = local[l - 1];
      box.lo = box.lo.cwiseMin(q);
      box.hi = box.hi.cwiseMax(q);
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
    o.aabb_min = ToVec(a.min);
    o.aabb_max = ToVec(a.max);
    o.obb_center = ToVec(f.centroid + f.axes * (0.5f * (f.lo + f.hi)));
    for (int j = 0; j < 3; ++j) o.obb_axes[j] = ToVec(f.axes.col(j));
    o.obb_extents = ToVec(f.hi - f.lo);
    o.mean_color = core::Rgb8{static_cast<uint8_t>(a.r / a.n), static_cast<uint8_t>(a.g / a.n),
                              static_cast<uint8_t>(a.b / a.n)};
    o.pixel_min_u = a.umin;
    o.pixel_min_v = a.vmin;
    o.pixel_max_u = a.umax;
    o.pixel_max_v = a.vmax;
    // Support plane: a support plane the object stands on has the object on its camera side
    // (positive signed distance, normals point to the camera) and nearly touches it. Pick
    // the one nearest to the object's lowest corner.
    float best = std::numeric_limits<float>::max();
    for (const Plane& pl : planes) {
      if (!pl.is_support) continue;
      const Eigen::Vector3f n(pl.normal.x, pl.normal.y, pl.normal.z);
      // Minimum signed distance over the AABB corners approximates the lowest point.
      float dmin = std::numeric_limits<float>::max();
      for (int c = 0; c < 8; ++c) {
        const Eigen::Vector3f corner((c & 1) ? a.max.x() : a.min.x(),
                                     (c & 2) ? a.max.y() : a.min.y(),
                                     (c & 4) ? a.max.z() : a.min.z());
        dmin = std::min(dmin, n.dot(corner) + pl.d);
      }
      const float dc = n.dot(f.centroid) + pl.d;
      if (dc <= 0.f) continue;  // the object is behind the plane
      if (std::abs(dmin) < best && std::abs(dmin) < 0.1f) {
        best = std::abs(dmin);
        o.support_plane_id = static_cast<int32_t>(pl.id);
      }
    }
    // Confidence: small objects and objects with few points relative to their box are less
    // certain; a simple monotone score in 0..1.
    o.confidence = std::clamp(static_cast<float>(a.n) / 2000.f, 0.2f, 1.f);
  }
}

}  // namespace clutterseg::pipeline
