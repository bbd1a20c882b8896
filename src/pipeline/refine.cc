#include "clutterseg/pipeline/refine.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "clutterseg/core/scoped_timer.h"

namespace clutterseg::pipeline {
namespace {

constexpr size_t kPixelGrain = 16384;

}  // namespace

int32_t Refiner::Find(int32_t x) {
  while (parent_[x] != x) {
    parent_[x] = parent_[parent_[x]];
    x = parent_[x];
  }
  return x;
}

void Refiner::Union(int32_t a, int32_t b) {
  a = Find(a);
  b = Find(b);
  if (a == b) return;
  if (a < b) std::swap(a, b);
  parent_[a] = b;  // the smaller id is the root: deterministic
}

bool Refiner::KeepGroup(const optimize::PlaneLabeling& planes, int32_t g) const {
  const ObjectParams& params = params_;
  if (group_points_[g] < static_cast<uint64_t>(params.min_object_points)) return false;
  if (params.below_support_margin_m <= 0.f) return true;
  // Segments below a support surface (the table's edge faces and legs, things under the
  // table) are not objects on it. Support normals point to the camera, so "below" is a
  // negative signed distance.
  const double inv = 1.0 / static_cast<double>(group_points_[g]);
  const core::Vec3f& c = group_centroid_[g];
  for (size_t p = 0; p < planes.planes.size(); ++p) {
    if (!support_[p]) continue;
    const core::Vec3f& nrm = planes.planes[p].normal;
    const double dist = (nrm.x * c.x + nrm.y * c.y + nrm.z * c.z) * inv + planes.planes[p].d;
    if (dist < -params.below_support_margin_m) return false;
  }
  return true;
}

Refiner::Refiner(const ObjectParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

void Refiner::Compute(const core::CameraIntrinsics& intrinsics, const core::PointCloud& cloud,
                      const supervoxel::Supervoxels& sv, const graph::PatchFeatures& features,
                      const graph::LinkageResult& link, const optimize::PlaneLabeling& planes,
                      SegmentationResult* result) {
  const core::ScopedTimer timer(&result->times[Stage::kRefine]);
  const ObjectParams& params = params_;
  core::ThreadPool* const pool = pool_;
  core::LabelImage* const labels = &result->labels;
  std::vector<Plane>* const out_planes = &result->planes;
  const size_t n = sv.size();
  const size_t num_planes = planes.planes.size();

  // Support planes are the large ones (table, floor, wall), measured by the metric area of
  // the surface assigned to them: a pixel at depth z seen at incidence angle t covers
  // z^2 / (fx fy cos t). Object faces are small even when they fill much of the image.
  plane_area_.assign(num_planes, 0.0);
  const double pixel_area = 1.0 / (intrinsics.fx * intrinsics.fy);
  for (size_t i = 0; i < n; ++i) {
    const int32_t p = planes.patch_plane[i];
    if (p < 0) continue;
    const core::Vec3f& c = features.centroid[i];
    const core::Vec3f& nrm = planes.planes[p].normal;
    const double r = std::sqrt(double(c.x) * c.x + double(c.y) * c.y + double(c.z) * c.z);
    if (!(r > 0.0)) continue;
    const double cos_t = std::max(0.2, std::abs((c.x * nrm.x + c.y * nrm.y + c.z * nrm.z) / r));
    plane_area_[p] += sv.num_points[i] * double(c.z) * c.z * pixel_area / cos_t;
  }
  support_.assign(num_planes, 0);
  out_planes->resize(num_planes);
  for (size_t p = 0; p < num_planes; ++p) {
    const optimize::PlaneModel& pm = planes.planes[p];
    support_[p] = plane_area_[p] >= params.support_min_area_m2 ? 1 : 0;
    Plane& out = (*out_planes)[p];
    out.id = static_cast<uint32_t>(p);
    out.normal = pm.normal;
    out.d = pm.d;
    out.num_points = pm.num_points;
    out.area_m2 = static_cast<float>(plane_area_[p]);
    out.is_support = support_[p] != 0;
  }

  background_.assign(n, 0);
  for (size_t i = 0; i < n; ++i) {
    const int32_t p = planes.patch_plane[i];
    if (p >= 0 && support_[p]) background_[i] = 1;
  }

  // Group foreground supervoxels: same initial segment and adjacent, or pieces of the same
  // non-support plane that touch.
  parent_.resize(n);
  std::iota(parent_.begin(), parent_.end(), 0);
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    for (uint32_t s = sv.adjacency_offsets[i]; s < sv.adjacency_offsets[i + 1]; ++s) {
      const uint32_t j = sv.adjacency[s];
      if (j <= i || background_[j]) continue;
      const bool same_segment = link.segment[i] == link.segment[j];
      const int32_t pi = planes.patch_plane[i];
      const bool same_plane = pi >= 0 && pi == planes.patch_plane[j] &&
                              features.type[i] == graph::PatchType::kPlanar &&
                              features.type[j] == graph::PatchType::kPlanar;
      if (same_segment || same_plane) Union(static_cast<int32_t>(i), static_cast<int32_t>(j));
    }
  }

  group_points_.assign(n, 0);
  group_centroid_.assign(n, core::Vec3f{});
  for (size_t i = 0; i < n; ++i) {
    if (background_[i]) continue;
    const int32_t g = Find(static_cast<int32_t>(i));
    const float w = static_cast<float>(sv.num_points[i]);
    group_points_[g] += sv.num_points[i];
    group_centroid_[g].x += w * features.centroid[i].x;
    group_centroid_[g].y += w * features.centroid[i].y;
    group_centroid_[g].z += w * features.centroid[i].z;
  }

  // Label groups in row-major order of their first pixel; drop small ones. Each band of
  // pixels lists the groups in the order they first appear in it; the bands' lists, in band
  // order, give every group's first appearance in the image. Pixels then take their
  // supervoxel's label from a table. Both tables are indexed by supervoxel + 1, so that an
  // invalid pixel (-1) needs no branch: group + 1 (0 for background and invalid pixels), and
  // the object label.
  sv_group_.resize(n + 1);
  sv_group_[0] = 0;
  for (size_t i = 0; i < n; ++i) {
    sv_group_[i + 1] = background_[i] ? 0 : Find(static_cast<int32_t>(i)) + 1;
  }
  const size_t num_pixels = sv.pixel_label.size();
  const size_t num_bands = core::ThreadPool::NumChunks(num_pixels, kPixelGrain);
  if (band_groups_.size() < num_bands) band_groups_.resize(num_bands);
  if (band_seen_.size() < num_bands) band_seen_.resize(num_bands);
  core::ForChunks(pool, num_pixels, kPixelGrain, [&](size_t b, size_t e) {
    std::vector<int32_t>& groups = band_groups_[b / kPixelGrain];
    std::vector<uint8_t>& seen = band_seen_[b / kPixelGrain];
    groups.clear();
    seen.assign(n + 1, 0);
    seen[0] = 1;  // background and invalid pixels
    const int32_t* pixel = sv.pixel_label.data();
    const int32_t* group = sv_group_.data();
    for (size_t px = b; px < e; ++px) {
      const int32_t g = group[pixel[px] + 1];
      if (seen[g]) continue;
      seen[g] = 1;
      groups.push_back(g - 1);
    }
  });
  group_label_.assign(n, -1);
  uint32_t next = 0;
  for (size_t k = 0; k < num_bands; ++k) {
    for (const int32_t g : band_groups_[k]) {
      if (group_label_[g] < 0) {
        group_label_[g] = KeepGroup(planes, g) ? static_cast<int32_t>(++next) : 0;
      }
    }
  }
  sv_label_.resize(n + 1);
  sv_label_[0] = 0;
  for (size_t i = 0; i < n; ++i) {
    const int32_t g = sv_group_[i + 1];
    sv_label_[i + 1] = g == 0 ? 0u : static_cast<uint32_t>(group_label_[g - 1]);
  }

  // Supervoxels straddle the contact between an object and its support: points of an object
  // that lie on a support plane go back to the background.
  const float snap = params.support_snap_distance_m;
  core::ForChunks(pool, num_pixels, kPixelGrain, [&](size_t b, size_t e) {
    const int32_t* pixel = sv.pixel_label.data();
    const uint32_t* label = sv_label_.data();
    uint32_t* out = labels->data.data();
    for (size_t px = b; px < e; ++px) out[px] = label[pixel[px] + 1];
    if (!(snap > 0.f)) return;
    for (size_t p = 0; p < num_planes; ++p) {
      if (!support_[p]) continue;
      const core::Vec3f nrm = planes.planes[p].normal;
      const float d = planes.planes[p].d;
      for (size_t px = b; px < e; ++px) {
        if (labels->data[px] == 0) continue;
        const core::Vec3f& q = cloud.xyz[px];
        if (std::abs(nrm.x * q.x + nrm.y * q.y + nrm.z * q.z + d) < snap) labels->data[px] = 0;
      }
    }
  });
  result->objects.assign(next, Object{});
}

}  // namespace clutterseg::pipeline
