#include "clutterseg/graph/patch_features.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "clutterseg/core/scoped_timer.h"
#include "clutterseg/geometry/moments.h"

namespace clutterseg::graph {
namespace {

// Per supervoxel: count, x, y, z, xx, xy, xz, yy, yz, zz.
constexpr size_t kMoments = geometry::kNumMoments;
// The image is split into this many row blocks (fewer for short images). The split depends
// only on the image height, so sums combined in block order do not depend on the pool.
constexpr int kMaxRowBlocks = 8;
constexpr size_t kPatchGrain = 256;

}  // namespace

void PatchFeatures::Resize(size_t n) {
  num_points.resize(n);
  centroid.resize(n);
  covariance.resize(n);
  eigenvalues.resize(n);
  normal.resize(n);
  curvature.resize(n);
  a1d.resize(n);
  a2d.resize(n);
  a3d.resize(n);
  type.resize(n);
}

namespace internal {

void FinishPatch(double n, const double sum[3], const double sum_sq[6], size_t i,
                 PatchFeatures* f) {
  f->num_points[i] = static_cast<uint32_t>(n);
  if (n <= 0.0) {
    f->centroid[i] = core::Vec3f{};
    f->covariance[i] = {};
    f->eigenvalues[i] = core::Vec3f{};
    f->normal[i] = core::Vec3f{0.f, 0.f, -1.f};
    f->curvature[i] = 0.f;
    f->a1d[i] = f->a2d[i] = f->a3d[i] = 0.f;
    f->type[i] = PatchType::kNonPlanar;
    return;
  }
  const double m[geometry::kNumMoments] = {n,         sum[0],    sum[1],    sum[2],    sum_sq[0],
                                           sum_sq[1], sum_sq[2], sum_sq[3], sum_sq[4], sum_sq[5]};
  geometry::ShapeSummary shape;
  geometry::SummarizeMoments(m, &shape);
  FinishPatchShape(n, shape, i, f);
}

void FinishPatchShape(double n, const geometry::ShapeSummary& shape, size_t i, PatchFeatures* f) {
  f->num_points[i] = static_cast<uint32_t>(n);
  f->centroid[i] = shape.centroid;
  f->covariance[i] = shape.covariance;
  f->eigenvalues[i] = shape.eigenvalues;
  f->normal[i] = shape.normal;
  f->curvature[i] = shape.curvature;
  const double l1 = shape.eigenvalues.x, l2 = shape.eigenvalues.y, l3 = shape.eigenvalues.z;
  const double s1 = std::sqrt(l1), s2 = std::sqrt(l2), s3 = std::sqrt(l3);
  if (s1 > 0.0 && n >= 3.0) {
    const float a1 = static_cast<float>((s1 - s2) / s1);
    const float a2 = static_cast<float>((s2 - s3) / s1);
    const float a3 = static_cast<float>(s3 / s1);
    f->a1d[i] = a1;
    f->a2d[i] = a2;
    f->a3d[i] = a3;
    f->type[i] = (a2 > a1 && a2 > a3) ? PatchType::kPlanar : PatchType::kNonPlanar;
  } else {
    f->a1d[i] = f->a2d[i] = f->a3d[i] = 0.f;
    f->type[i] = PatchType::kNonPlanar;
  }
}

}  // namespace internal

void PatchFeatureExtractor::Compute(const core::PointCloud& cloud,
                                    const supervoxel::Supervoxels& sv, PatchFeatures* f) {
  const core::ScopedTimer timer(&f->time_ms);
  const size_t num_sv = sv.size();
  const size_t num_pixels = static_cast<size_t>(sv.width) * static_cast<size_t>(sv.height);
  if (cloud.width != sv.width || cloud.height != sv.height || cloud.xyz.size() != num_pixels ||
      sv.pixel_label.size() != num_pixels) {
    throw std::runtime_error(
        "PatchFeatureExtractor: cloud (" + std::to_string(cloud.width) + "x" +
        std::to_string(cloud.height) + ", " + std::to_string(cloud.xyz.size()) +
        " points) does not match the supervoxel image (" + std::to_string(sv.width) + "x" +
        std::to_string(sv.height) + ", " + std::to_string(sv.pixel_label.size()) + " labels)");
  }
  f->Resize(num_sv);
  if (num_sv == 0) return;
  if (sv.moments.size() == num_sv * kMoments) {
    // The supervoxelizer kept its members' moments: no pass over the pixels. From 3 points
    // on it also summarised them exactly as SummarizeMoments does: only the covariance is
    // left to compute (no second eigen-solve).
    auto finish_from_sv = [&](size_t i0, size_t i1) {
      for (size_t i = i0; i < i1; ++i) {
        const double* m = &sv.moments[i * kMoments];
        if (m[0] < 3.0) {
          internal::FinishPatch(m[0], m + 1, m + 4, i, f);
          continue;
        }
        geometry::ShapeSummary shape;
        double mean[3], cov[6];
        geometry::MomentsCovariance(m, mean, cov);
        for (int k = 0; k < 6; ++k)
          shape.covariance[static_cast<size_t>(k)] = static_cast<float>(cov[k]);
        shape.centroid = sv.centroid[i];
        shape.eigenvalues = sv.eigenvalues[i];
        shape.normal = sv.normal[i];
        shape.curvature = sv.curvature[i];
        internal::FinishPatchShape(m[0], shape, i, f);
      }
    };
    core::ForChunks(pool_, num_sv, kPatchGrain, finish_from_sv);
    return;
  }

  const int height = sv.height;
  const int width = sv.width;
  const int rows_per_block = std::max(1, (height + kMaxRowBlocks - 1) / kMaxRowBlocks);
  const size_t num_blocks =
      height > 0 ? static_cast<size_t>((height + rows_per_block - 1) / rows_per_block) : 0;
  const size_t stride = num_sv * kMoments;
  block_sums_.assign(num_blocks * stride, 0.0);
  std::vector<uint8_t>& bad_label = bad_block_;
  bad_label.assign(num_blocks, 0);

  auto accumulate = [&](size_t b0, size_t b1) {
    for (size_t b = b0; b < b1; ++b) {
      double* sums = block_sums_.data() + b * stride;
      const int v0 = static_cast<int>(b) * rows_per_block;
      const int v1 = std::min(height, v0 + rows_per_block);
      for (int v = v0; v < v1; ++v) {
        const size_t row = static_cast<size_t>(v) * width;
        // Runs of equal labels along the row are summed in registers, then flushed.
        int32_t run_id = -1;
        double r[kMoments] = {};
        auto flush = [&]() {
          if (run_id < 0) return;
          double* s = sums + static_cast<size_t>(run_id) * kMoments;
          for (size_t k = 0; k < kMoments; ++k) s[k] += r[k];
        };
        for (int u = 0; u < width; ++u) {
          const int32_t id = sv.pixel_label[row + u];
          if (id < 0) continue;
          if (static_cast<size_t>(id) >= num_sv) {
            bad_label[b] = 1;
            continue;
          }
          const core::Vec3f& p = cloud.xyz[row + u];
          if (!core::IsValid(p)) continue;
          if (id != run_id) {
            flush();
            run_id = id;
            for (double& x : r) x = 0.0;
          }
          geometry::AddToMoments(p, r);
        }
        flush();
      }
    }
  };
  core::ForChunks(pool_, num_blocks, 1, accumulate);
  for (uint8_t bad : bad_label) {
    if (bad) {
      throw std::runtime_error(
          "PatchFeatureExtractor: a pixel label is >= the number of "
          "supervoxels (" +
          std::to_string(num_sv) + ")");
    }
  }

  auto finish = [&](size_t i0, size_t i1) {
    for (size_t i = i0; i < i1; ++i) {
      double m[kMoments] = {};
      for (size_t b = 0; b < num_blocks; ++b) {
        const double* s = block_sums_.data() + b * stride + i * kMoments;
        for (size_t k = 0; k < kMoments; ++k) m[k] += s[k];
      }
      internal::FinishPatch(m[0], m + 1, m + 4, i, f);
    }
  };
  core::ForChunks(pool_, num_sv, kPatchGrain, finish);
}

}  // namespace clutterseg::graph
