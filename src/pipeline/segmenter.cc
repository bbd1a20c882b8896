#include "clutterseg/pipeline/segmenter.h"

#include <chrono>

#include "clutterseg/core/label_scan.h"
#include "clutterseg/core/thread_pool.h"
#include "clutterseg/geometry/planar_regions.h"
#include "clutterseg/graph/linkage.h"
#include "clutterseg/graph/patch_features.h"
#include "clutterseg/optimize/planes.h"
#include "clutterseg/pipeline/neck_cut.h"
#include "clutterseg/pipeline/objects.h"
#include "clutterseg/pipeline/refine.h"
#include "clutterseg/pipeline/stack_cut.h"
#include "clutterseg/pipeline/working_cloud.h"
#include "clutterseg/supervoxel/supervoxelizer.h"

namespace clutterseg::pipeline {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

// The stages, each built once from its params and the pool, and their outputs.
struct Segmenter::Impl {
  Impl(const SegmenterParams& p, core::ThreadPool* thread_pool)
      : params((p.ValidateOrThrow(), p)),
        pool(thread_pool),
        points(p.points, thread_pool),
        support(p.support, thread_pool),
        supervoxelizer(p.supervoxel, thread_pool),
        features(thread_pool),
        linkage(p.linkage, thread_pool),
        plane_labeler(p.planes),
        refiner(p.objects, thread_pool),
        stack_cut(p.objects, thread_pool),
        neck_cut(p.objects, thread_pool),
        objects(thread_pool) {}

  const SegmenterParams params;
  core::ThreadPool* pool;  // may be null
  WorkingCloudBuilder points;
  geometry::PlanarRegionFinder support;
  supervoxel::Supervoxelizer supervoxelizer;
  graph::PatchFeatureExtractor features;
  graph::Linkage linkage;
  optimize::PlaneLabeler plane_labeler;
  Refiner refiner;
  StackCutter stack_cut;
  NeckCutter neck_cut;
  ObjectExtractor objects;

  WorkingCloud work;
  std::vector<float> scene_z;  // the working cloud's z before the support-first step
  geometry::PlanarRegions regions;
  std::vector<optimize::PlaneModel> fixed_planes;
  supervoxel::Supervoxels sv;
  graph::PatchFeatures patch;
  graph::LinkageResult link;
  optimize::PlaneLabeling planes;
};

Segmenter::Segmenter(const SegmenterParams& params, core::ThreadPool* pool)
    : impl_(std::make_unique<Impl>(params, pool)) {}

Segmenter::~Segmenter() = default;

const SegmenterParams& Segmenter::params() const { return impl_->params; }

const core::PointCloud& Segmenter::working_cloud() const { return impl_->work.cloud; }

const std::vector<float>& Segmenter::scene_depth() const { return impl_->scene_z; }

void Segmenter::Process(const core::PointCloudView& cloud, const core::CameraIntrinsics& intrinsics,
                        SegmentationResult* result) {
  Impl& m = *impl_;
  const auto t_start = Clock::now();
  result->times = StageTimes{};
  // The supervoxels use colour only with a colour weight; the objects read the input's.
  m.points.Compute(cloud, m.params.supervoxel.color_importance > 0.f, &m.work);
  result->times[Stage::kPoints] = m.work.time_ms;
  Segment(cloud, intrinsics, result);
  result->times.total_ms = MsSince(t_start);
}

void Segmenter::ProcessDepth(const core::DepthImage& depth, const core::ColorImage* color,
                             const core::CameraIntrinsics& intrinsics, SegmentationResult* result) {
  Impl& m = *impl_;
  const auto t_start = Clock::now();
  result->times = StageTimes{};
  m.points.Compute(depth, color, intrinsics, &m.work);
  result->times[Stage::kPoints] = m.work.time_ms;
  Segment(m.work.cloud, intrinsics, result);
  result->times.total_ms = MsSince(t_start);
}

void Segmenter::Segment(const core::PointCloudView& cloud, const core::CameraIntrinsics& intrinsics,
                        SegmentationResult* result) {
  Impl& m = *impl_;
  StageTimes& times = result->times;
  const core::PointCloud& work = m.work.cloud;
  result->width = work.width;
  result->height = work.height;
  result->num_valid_points = m.work.num_valid;
  result->labels.Reset(work.width, work.height, 0u);
  result->objects.clear();
  result->planes.clear();
  result->num_supervoxels = 0;
  result->num_support_first_points = 0;
  result->supervoxels_capped = false;
  result->objects_capped = false;
  m.scene_z.clear();
  if (m.params.partition.arrival_gap_frames > 0 && work.organized()) {
    m.scene_z.resize(work.size());
    core::ForChunks(m.pool, work.size(), core::kPixelGrain, [&](size_t b, size_t e) {
      for (size_t i = b; i < e; ++i) m.scene_z[i] = work.xyz[i].z;
    });
  }
  if (m.work.num_valid == 0) return;

  // Support first: the interior of the large planes leaves the working cloud (the points
  // stay in the input, and in `cloud`), and their planes go to the plane labelling as fixed
  // planes carrying the points and area they took (PlaneLabeler::Compute).
  m.support.Compute(intrinsics, m.params.objects.support_min_area_m2, &m.work.cloud, &m.regions);
  times[Stage::kSupport] = m.regions.time_ms;
  result->num_support_first_points = m.regions.num_taken_points;
  m.fixed_planes.clear();
  for (const geometry::PlanarRegion& r : m.regions.regions) {
    optimize::PlaneModel pm;
    pm.normal = r.normal;
    pm.d = r.d;
    pm.fixed_points = r.num_taken_points;
    pm.fixed_area_m2 = r.taken_area_m2;
    m.fixed_planes.push_back(pm);
  }

  m.supervoxelizer.Compute(work, &m.sv);
  const supervoxel::SupervoxelTimings& st = m.sv.timings;
  times[Stage::kVoxelize] = st.voxelize_ms + st.adjacency_ms;
  times[Stage::kNormals] = st.normals_ms;
  times[Stage::kSeeding] = st.seeding_ms;
  times[Stage::kGrowth] = st.growth_ms;
  times[Stage::kSupervoxelStats] = st.output_ms;
  result->num_supervoxels = static_cast<uint32_t>(m.sv.size());
  result->supervoxels_capped = m.sv.capped;

  m.features.Compute(work, m.sv, &m.patch);
  times[Stage::kFeatures] = m.patch.time_ms;

  // The border cues read the input's depths and colour (the working cloud's points are the
  // input's wherever a supervoxel is), and for an unorganized cloud the voxels.
  graph::LinkageCues cues;
  cues.cloud = cloud;
  if (!work.organized()) {
    cues.voxels = &m.supervoxelizer.voxels();
    cues.voxel_supervoxel = &m.supervoxelizer.voxel_label();
  }
  // The linkage and the plane labelling read the same supervoxels and features and nothing of
  // each other. They run as the two chunks of one parallel loop: a pool worker labels the
  // planes (serial work: hypotheses, then alpha-expansion) while this thread computes the
  // linkage, whose own loops fan out again, so the worker takes their chunks as soon as the
  // planes are done (on mOSD frames the planes take a fifth of the linkage's time). Chunks
  // never change a result. Without a free worker this thread runs both, one after the other.
  // The linkage's mean chromaticities (a pass over the label image) are computed first, on
  // the whole pool.
  const auto t_cues = Clock::now();
  m.linkage.PrepareCues(m.sv, cues);
  const double cues_ms = MsSince(t_cues);
  core::ForChunks(m.pool, 2, 1, [&](size_t begin, size_t) {
    if (begin == 0) {
      m.linkage.Compute(m.sv, m.patch, cues, &m.link);
    } else {
      m.plane_labeler.Compute(m.sv, m.patch, m.fixed_planes, &m.planes);
    }
  });
  times[Stage::kLinkage] = cues_ms + m.link.time_ms;
  times[Stage::kPlanes] = m.planes.hypotheses_ms;
  times[Stage::kExpansion] = m.planes.expansion_ms;

  m.refiner.Compute(intrinsics, work, m.sv, m.patch, m.link, m.planes, result, &m.regions);
  m.stack_cut.Compute(cloud, m.sv, result);
  m.neck_cut.Compute(cloud, intrinsics, result);
  m.objects.Compute(cloud, result);
}

}  // namespace clutterseg::pipeline
