#include "clutterseg/pipeline/segmenter.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "clutterseg/core/simd_points.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/graph/linkage.h"
#include "clutterseg/graph/patch_features.h"
#include "clutterseg/optimize/planes.h"
#include "clutterseg/pipeline/objects.h"
#include "clutterseg/pipeline/refine.h"
#include "clutterseg/supervoxel/supervoxelizer.h"

namespace clutterseg::pipeline {
namespace {

using Clock = std::chrono::steady_clock;
constexpr size_t kPointGrain = 32768;

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Copies points [0, n) from `src` to `dst`, a point outside the depth range [zmin, zmax] or
// with a non-finite coordinate becoming invalid (NaN); returns the number kept. Branch-free
// (valid and invalid points interleave along object edges): a coordinate is finite exactly
// when its magnitude is below infinity.
uint32_t RestrictToDepthRange(const core::Vec3f* src, core::Vec3f* dst, size_t n, float zmin,
                              float zmax) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const core::Vec3f invalid{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth};
  uint32_t valid = 0;
  size_t i = 0;
#if defined(__SSE2__)
  // Four points at a time.
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 inf = _mm_set1_ps(kInf), lo = _mm_set1_ps(zmin), hi = _mm_set1_ps(zmax);
  const __m128 nan = _mm_set1_ps(core::kInvalidDepth);
  for (; i + 4 <= n; i += 4) {
    const core::FourPoints p = core::LoadFourPoints(src + i);
    const __m128 finite = _mm_and_ps(_mm_and_ps(_mm_cmplt_ps(_mm_and_ps(p.x, abs_mask), inf),
                                                _mm_cmplt_ps(_mm_and_ps(p.y, abs_mask), inf)),
                                     _mm_cmplt_ps(_mm_and_ps(p.z, abs_mask), inf));
    const __m128 keep =
        _mm_and_ps(finite, _mm_and_ps(_mm_cmpge_ps(p.z, lo), _mm_cmple_ps(p.z, hi)));
    valid += core::CountLanes(keep);
    core::StoreFourPointsWhere(keep, p, nan, dst + i);
  }
#endif
  for (; i < n; ++i) {
    const core::Vec3f p = src[i];
    const float ax = std::fabs(p.x), ay = std::fabs(p.y), az = std::fabs(p.z);
    const bool ok = (ax < kInf) & (ay < kInf) & (az < kInf) & (p.z >= zmin) & (p.z <= zmax);
    dst[i] = ok ? p : invalid;
    valid += ok ? 1u : 0u;
  }
  return valid;
}

}  // namespace

struct Segmenter::Impl {
  Impl(const SegmenterParams& p, core::ThreadPool* thread_pool)
      : params((p.ValidateOrThrow(), p)),
        pool(thread_pool),
        supervoxelizer(p.supervoxel),
        features(thread_pool),
        linkage(p.linkage, thread_pool),
        plane_labeler(p.planes) {}

  const SegmenterParams params;
  core::ThreadPool* pool;
  supervoxel::Supervoxelizer supervoxelizer;
  graph::PatchFeatureExtractor features;
  graph::Linkage linkage;
  optimize::PlaneLabeler plane_labeler;
  Refiner refiner;
  ObjectExtractor objects;

  core::PointCloud work;              // the input restricted to the working depth range
  std::vector<uint32_t> chunk_valid;  // valid points per chunk of the restriction
  supervoxel::Supervoxels sv;
  graph::PatchFeatures patch;
  graph::LinkageResult link;
  optimize::PlaneLabeling planes;
};

Segmenter::Segmenter(const SegmenterParams& params, core::ThreadPool* pool)
    : impl_(std::make_unique<Impl>(params, pool)) {}

Segmenter::~Segmenter() = default;

const SegmenterParams& Segmenter::params() const { return impl_->params; }

void Segmenter::SetPool(core::ThreadPool* pool) {
  impl_->pool = pool;
  impl_->features.set_pool(pool);
  impl_->linkage.set_pool(pool);
}

void Segmenter::Process(const core::PointCloud& cloud, const core::CameraIntrinsics& intrinsics,
                        SegmentationResult* result) {
  Impl& m = *impl_;
  const auto t_start = Clock::now();
  result->times = StageTimes{};

  // Working cloud: points outside the depth range become invalid.
  m.work.width = cloud.width;
  m.work.height = std::max(cloud.height, 1);
  m.work.xyz.resize(cloud.xyz.size());
  const float zmin = m.params.objects.min_depth_m;
  const float zmax = m.params.objects.max_depth_m;
  const core::Vec3f* src = cloud.xyz.data();
  core::Vec3f* dst = m.work.xyz.data();
  const size_t n = cloud.xyz.size();
  const size_t num_chunks = core::ThreadPool::NumChunks(n, kPointGrain);
  m.chunk_valid.assign(num_chunks, 0);
  auto restrict_points = [&](size_t b, size_t e) {
    m.chunk_valid[b / kPointGrain] = RestrictToDepthRange(src + b, dst + b, e - b, zmin, zmax);
  };
  core::ForChunks(m.pool, n, kPointGrain, restrict_points);
  const auto num_valid =
      static_cast<uint32_t>(std::accumulate(m.chunk_valid.begin(), m.chunk_valid.end(), 0u));
  if (m.params.supervoxel.color_importance > 0.f && cloud.has_color()) {
    m.work.rgba = cloud.rgba;
  } else {
    m.work.rgba.clear();
  }
  result->times.points_ms = MsSince(t_start);
  Segment(cloud, intrinsics, num_valid, t_start, result);
}

void Segmenter::ProcessDepth(const core::DepthImage& depth, const core::ColorImage* color,
                             const core::CameraIntrinsics& intrinsics, SegmentationResult* result) {
  Impl& m = *impl_;
  const auto t_start = Clock::now();
  result->times = StageTimes{};
  // Back-projected straight into the working cloud, restricted to the depth range. Its
  // colour is used by the supervoxels only when color_importance > 0, by the objects always.
  const size_t num_valid =
      core::DepthToPointCloud(depth, intrinsics, color, &m.work, m.params.objects.min_depth_m,
                              m.params.objects.max_depth_m, m.pool);
  result->times.points_ms = MsSince(t_start);
  Segment(m.work, intrinsics, static_cast<uint32_t>(num_valid), t_start, result);
}

const core::PointCloud& Segmenter::working_cloud() const { return impl_->work; }

void Segmenter::Segment(const core::PointCloud& cloud, const core::CameraIntrinsics& intrinsics,
                        uint32_t num_valid, Clock::time_point t_start, SegmentationResult* result) {
  Impl& m = *impl_;
  StageTimes& times = result->times;
  const int width = m.work.width;
  const int height = m.work.height;
  result->width = width;
  result->height = height;
  result->num_valid_points = num_valid;
  result->labels.Reset(width, height, 0u);
  result->objects.clear();
  result->planes.clear();
  result->num_supervoxels = 0;
  if (num_valid == 0) {
    times.total_ms = MsSince(t_start);
    return;
  }

  auto t0 = Clock::now();
  m.supervoxelizer.Compute(m.work, m.pool, &m.sv);
  const supervoxel::SupervoxelTimings& st = m.supervoxelizer.timings();
  times.voxelize_ms = st.voxelize_ms + st.adjacency_ms;
  times.normals_ms = st.normals_ms;
  times.seeding_ms = st.seeding_ms;
  times.growth_ms = st.growth_ms;
  times.supervoxels_ms = MsSince(t0);
  result->num_supervoxels = static_cast<uint32_t>(m.sv.size());

  t0 = Clock::now();
  m.features.Compute(m.work, m.sv, &m.patch);
  times.features_ms = MsSince(t0);

  t0 = Clock::now();
  m.linkage.Compute(m.sv, m.patch, &m.link);
  times.linkage_ms = MsSince(t0);

  t0 = Clock::now();
  m.plane_labeler.Compute(m.sv, m.patch, &m.planes);
  times.expansion_ms = m.plane_labeler.last_expansion_ms();
  times.planes_ms = std::max(0.0, MsSince(t0) - times.expansion_ms);

  t0 = Clock::now();
  const uint32_t num_objects =
      m.refiner.Run(m.params.objects, intrinsics, m.work, m.sv, m.patch, m.link, m.planes,
                    &result->labels, &result->planes, m.pool);
  m.objects.Compute(cloud, result->labels, num_objects, result->planes, &result->objects, m.pool);
  times.objects_ms = MsSince(t0);
  times.total_ms = MsSince(t_start);
}

}  // namespace clutterseg::pipeline
