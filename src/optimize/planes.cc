#include "clutterseg/optimize/planes.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace clutterseg::optimize {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

float Dot(const core::Vec3f& a, const core::Vec3f& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

}  // namespace

namespace internal {

bool FitPlane(const graph::PatchFeatures& f, const std::vector<uint32_t>& patches,
              core::Vec3f* normal, float* d, uint32_t* num_points) {
  double total = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (uint32_t i : patches) {
    const double n = f.num_points[i];
    total += n;
    mean += n * Eigen::Vector3d(f.centroid[i].x, f.centroid[i].y, f.centroid[i].z);
  }
  *num_points = static_cast<uint32_t>(total);
  if (total < 3.0) return false;
  mean /= total;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (uint32_t i : patches) {
    const double n = f.num_points[i];
    if (n <= 0.0) continue;
    const auto& c = f.covariance[i];
    Eigen::Matrix3d cov;
    cov << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
    const Eigen::Vector3d dc =
        Eigen::Vector3d(f.centroid[i].x, f.centroid[i].y, f.centroid[i].z) - mean;
    scatter += n * (cov + dc * dc.transpose());
  }
  scatter /= total;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(scatter);
  Eigen::Vector3d nrm = solver.eigenvectors().col(0);
  if (!nrm.allFinite() || !(nrm.norm() > 0.0)) return false;
  nrm.normalize();
  if (nrm.dot(mean) > 0.0) nrm = -nrm;
  *normal = core::Vec3f{static_cast<float>(nrm.x()), static_cast<float>(nrm.y()),
                        static_cast<float>(nrm.z())};
  *d = static_cast<float>(-nrm.dot(mean));
  return true;
}

}  // namespace internal

PlaneLabeler::PlaneLabeler(const PlaneParams& params)
    : params_((params.ValidateOrThrow(), params)) {}

void PlaneLabeler::PackPatches(const graph::PatchFeatures& f) {
  packed_.clear();
  const auto min_points = static_cast<uint32_t>(params_.min_patch_points);
  for (size_t i = 0; i < f.size(); ++i) {
    if (f.num_points[i] < min_points) continue;
    packed_.push_back(PackedPatch{f.centroid[i], f.normal[i], static_cast<uint32_t>(i)});
  }
  const size_t padded = (packed_.size() + 3) / 4 * 4;
  for (std::vector<float>& plane : soa_) plane.assign(padded, 0.f);
  for (size_t k = 0; k < packed_.size(); ++k) {
    soa_[0][k] = packed_[k].centroid.x;
    soa_[1][k] = packed_[k].centroid.y;
    soa_[2][k] = packed_[k].centroid.z;
    soa_[3][k] = packed_[k].normal.x;
    soa_[4][k] = packed_[k].normal.y;
    soa_[5][k] = packed_[k].normal.z;
  }
  // Packed patches by x, for the neighbourhood queries (ties by position: a total order).
  by_x_.resize(packed_.size());
  for (size_t k = 0; k < packed_.size(); ++k) {
    by_x_[k] = {packed_[k].centroid.x, static_cast<uint32_t>(k)};
  }
  std::sort(by_x_.begin(), by_x_.end());
}

void PlaneLabeler::CollectInliers(const core::Vec3f& normal, float d, float tolerance_scale,
                                  const core::Vec3f* center, float radius_m,
                                  std::vector<uint32_t>* inliers) {
  inliers->clear();
  const float rho = params_.inlier_distance_m * tolerance_scale;
  const float min_cos = static_cast<float>(
      std::cos(std::min(89.0, double{params_.inlier_angle_deg} * tolerance_scale) * kDegToRad));
  if (center != nullptr) {
    // Only patches whose x lies within the radius (widened by a margin that covers rounding)
    // can pass; their positions are sorted so that the inliers come in packed order, as from
    // a full scan.
    const float r2 = radius_m * radius_m;
    const float margin = radius_m * 1.001f + 1e-6f;
    std::vector<uint32_t>& near = near_;
    near.clear();
    auto it = std::lower_bound(by_x_.begin(), by_x_.end(),
                               std::pair<float, uint32_t>{center->x - margin, 0u});
    for (; it != by_x_.end() && it->first <= center->x + margin; ++it) {
      const PackedPatch& p = packed_[it->second];
      const float dx = p.centroid.x - center->x, dy = p.centroid.y - center->y,
                  dz = p.centroid.z - center->z;
      if (dx * dx + dy * dy + dz * dz > r2) continue;
      if (std::fabs(Dot(normal, p.centroid) + d) > rho) continue;
      if (Dot(normal, p.normal) < min_cos) continue;
      near.push_back(it->second);
    }
    std::sort(near.begin(), near.end());
    for (const uint32_t k : near) inliers->push_back(packed_[k].index);
    return;
  }
  size_t k = 0;
#if defined(__SSE2__)
  // Four patches at a time, the tests evaluated as the scalar ones below (same operations in
  // the same order; "not greater" and "not less" let NaN pass as the scalar tests do). Each
  // patch is written and kept by its bit, without a branch.
  const size_t num_packed = packed_.size();
  inliers->resize(num_packed + 4);
  uint32_t* out = inliers->data();
  size_t size = 0;
  const __m128 nx = _mm_set1_ps(normal.x), ny = _mm_set1_ps(normal.y), nz = _mm_set1_ps(normal.z);
  const __m128 vd = _mm_set1_ps(d), vrho = _mm_set1_ps(rho), vcos = _mm_set1_ps(min_cos);
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  for (; k + 4 <= soa_[0].size(); k += 4) {
    const __m128 dist = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, _mm_loadu_ps(&soa_[0][k])),
                                                         _mm_mul_ps(ny, _mm_loadu_ps(&soa_[1][k]))),
                                              _mm_mul_ps(nz, _mm_loadu_ps(&soa_[2][k]))),
                                   vd);
    const __m128 cos = _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, _mm_loadu_ps(&soa_[3][k])),
                                             _mm_mul_ps(ny, _mm_loadu_ps(&soa_[4][k]))),
                                  _mm_mul_ps(nz, _mm_loadu_ps(&soa_[5][k])));
    const int keep = _mm_movemask_ps(
        _mm_and_ps(_mm_cmpngt_ps(_mm_and_ps(dist, abs_mask), vrho), _mm_cmpnlt_ps(cos, vcos)));
    for (int j = 0; j < 4; ++j) {
      out[size] = k + j < num_packed ? packed_[k + j].index : 0u;
      size += static_cast<size_t>((keep >> j) & 1);
    }
  }
  inliers->resize(size);
#endif
  for (; k < packed_.size(); ++k) {
    const PackedPatch& p = packed_[k];
    if (std::fabs(Dot(normal, p.centroid) + d) > rho) continue;
    if (Dot(normal, p.normal) < min_cos) continue;
    inliers->push_back(p.index);
  }
}

void PlaneLabeler::FindPlanes(const graph::PatchFeatures& f, std::vector<PlaneModel>* planes) {
  planes->clear();
  const size_t n = f.size();
  const auto min_points = static_cast<uint32_t>(params_.min_patch_points);
  seeds_.clear();
  for (size_t i = 0; i < n; ++i) {
    if (f.type[i] == graph::PatchType::kPlanar && f.num_points[i] >= min_points &&
        f.curvature[i] <= params_.max_seed_curvature) {
      seeds_.push_back(static_cast<uint32_t>(i));
    }
  }
  // Flattest first; ties by index (std::sort with a total order: no temporary buffer).
  std::sort(seeds_.begin(), seeds_.end(), [&](uint32_t a, uint32_t b) {
    return f.curvature[a] < f.curvature[b] || (f.curvature[a] == f.curvature[b] && a < b);
  });
  covered_.assign(n, 0);
  PackPatches(f);
  const float dup_cos = static_cast<float>(std::cos(params_.duplicate_angle_deg * kDegToRad));
  const auto min_inliers = static_cast<size_t>(params_.min_inlier_patches);

  // Phase 1: grow a refitted candidate from each uncovered seed, flattest seeds first. A
  // candidate's inliers are covered, so each surface is tried about once.
  candidates_.clear();
  int trials = 0;
  for (uint32_t seed : seeds_) {
    if (trials >= params_.max_candidate_trials) break;
    if (covered_[seed]) continue;
    ++trials;
    core::Vec3f normal = f.normal[seed];
    float d = -Dot(normal, f.centroid[seed]);
    uint32_t points = 0;
    // A single patch's normal is noisy: first fit the plane to the seed's neighbourhood
    // (looser tolerances, within seed_neighborhood_m), then collect inliers globally.
    if (params_.seed_neighborhood_m > 0.f) {
      CollectInliers(normal, d, 2.f, &f.centroid[seed], params_.seed_neighborhood_m, &inliers_);
      if (inliers_.size() >= 3) internal::FitPlane(f, inliers_, &normal, &d, &points);
    }
    CollectInliers(normal, d, 1.f, nullptr, 0.f, &inliers_);
    if (inliers_.size() < min_inliers) {
      // The seeds of a surface too small for a plane would all repeat this failing trial.
      for (uint32_t i : inliers_) covered_[i] = 1;
      continue;
    }
    bool ok = true;
    for (int it = 0; it <= params_.refit_iterations && ok; ++it) {
      ok = internal::FitPlane(f, inliers_, &normal, &d, &points);
      if (ok && it < params_.refit_iterations)
        CollectInliers(normal, d, 1.f, nullptr, 0.f, &inliers_);
    }
    if (!ok || inliers_.size() < min_inliers) continue;
    double sx = 0, sy = 0, sz = 0, sn = 0;
    for (uint32_t i : inliers_) {
      covered_[i] = 1;
      sx += double{f.centroid[i].x} * f.num_points[i];
      sy += double{f.centroid[i].y} * f.num_points[i];
      sz += double{f.centroid[i].z} * f.num_points[i];
      sn += f.num_points[i];
    }
    Candidate c;
    c.order = static_cast<uint32_t>(candidates_.size());
    c.model = PlaneModel{normal, d, points, static_cast<uint32_t>(inliers_.size())};
    c.inlier_centroid = core::Vec3f{static_cast<float>(sx / sn), static_cast<float>(sy / sn),
                                    static_cast<float>(sz / sn)};
    candidates_.push_back(c);
  }

  // Phase 2: accept the largest candidates first (by inlier points; with
  // accept_largest_first off, in seed order as the paper), skipping duplicates of
  // accepted planes. Accepting in order of flatness instead lets many small, perfectly flat
  // surfaces (e.g. the depth-quantisation terraces of far background) use up max_planes
  // before the table is reached.
  if (params_.accept_largest_first) {
    std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
      return a.model.num_points > b.model.num_points ||
             (a.model.num_points == b.model.num_points && a.order < b.order);
    });
  }
  for (const Candidate& c : candidates_) {
    if (static_cast<int>(planes->size()) >= params_.max_planes) break;
    bool duplicate = false;
    for (const PlaneModel& q : *planes) {
      if (Dot(q.normal, c.model.normal) >= dup_cos &&
          std::fabs(Dot(q.normal, c.inlier_centroid) + q.d) < params_.duplicate_distance_m) {
        duplicate = true;
        break;
      }
    }
    if (!duplicate) planes->push_back(c.model);
  }
}

void PlaneLabeler::Compute(const supervoxel::Supervoxels& sv, const graph::PatchFeatures& f,
                           PlaneLabeling* out) {
  Compute(sv, f, {}, out);
}

void PlaneLabeler::Compute(const supervoxel::Supervoxels& sv, const graph::PatchFeatures& f,
                           const std::vector<PlaneModel>& fixed, PlaneLabeling* out) {
  const auto t0 = std::chrono::steady_clock::now();
  out->expansion_ms = 0.0;
  Label(sv, f, fixed, out);
  const double total_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  out->hypotheses_ms = std::max(0.0, total_ms - out->expansion_ms);
}

void PlaneLabeler::Label(const supervoxel::Supervoxels& sv, const graph::PatchFeatures& f,
                         const std::vector<PlaneModel>& fixed, PlaneLabeling* out) {
  const size_t n = sv.size();
  if (f.size() != n || f.num_points.size() != n || f.a2d.size() != n) {
    throw std::runtime_error("PlaneLabeler: features have " + std::to_string(f.size()) +
                             " entries for " + std::to_string(n) + " supervoxels");
  }
  if (sv.adjacency_offsets.size() != n + 1 ||
      (n > 0 && sv.adjacency_offsets.back() != sv.adjacency.size())) {
    throw std::runtime_error("PlaneLabeler: adjacency_offsets has " +
                             std::to_string(sv.adjacency_offsets.size()) + " entries for " +
                             std::to_string(n) + " supervoxels");
  }
  FindPlanes(f, &found_);
  // A fixed plane along a found one (normals within duplicate_angle_deg, offsets within
  // duplicate_distance_m) is the same surface: the found plane takes its points and area. It
  // keeps its own fit, to the patches the supervoxels see of the plane (the ring around each
  // object, which it follows best there), unless the normals differ by more than
  // fixed_fit_max_angle_deg: a flat object's top a centimetre or two above the ring has then
  // pulled the found plane over (a book lying alone on the table), and the fixed plane's fit,
  // to the whole interior on the pixel grid, is taken. A fixed plane with no match is a
  // hypothesis of its own, ahead of the found ones.
  const float dup_cos = static_cast<float>(std::cos(params_.duplicate_angle_deg * kDegToRad));
  const float keep_cos = static_cast<float>(std::cos(params_.fixed_fit_max_angle_deg * kDegToRad));
  hypotheses_.clear();
  for (const PlaneModel& p : fixed) {
    PlaneModel* match = nullptr;
    for (PlaneModel& q : found_) {
      if (Dot(p.normal, q.normal) >= dup_cos &&
          std::fabs(p.d - q.d) < params_.duplicate_distance_m) {
        match = &q;
        break;
      }
    }
    if (match != nullptr) {
      match->fixed_points += p.fixed_points;
      match->fixed_area_m2 += p.fixed_area_m2;
      if (Dot(p.normal, match->normal) < keep_cos) {
        match->normal = p.normal;
        match->d = p.d;
      }
    } else {
      hypotheses_.push_back(p);
    }
  }
  const size_t num_fixed = hypotheses_.size();  // kept in the output even with no supervoxel
  for (const PlaneModel& q : found_) hypotheses_.push_back(q);
  out->num_hypotheses = static_cast<int>(hypotheses_.size());
  out->planes.clear();
  out->patch_plane.assign(n, -1);
  out->energy = 0.0;
  out->expansion_cycles = 0;
  if (n == 0 || hypotheses_.empty()) {
    out->planes.assign(hypotheses_.begin(), hypotheses_.begin() + num_fixed);
    for (PlaneModel& p : out->planes) p.num_points = p.num_patches = 0;
    return;
  }

  // Unary costs in units of rho; label p < P is plane p, label P is l0.
  const size_t num_planes = hypotheses_.size();
  const size_t num_labels = num_planes + 1;
  const float rho = params_.inlier_distance_m;
  const float min_cos = static_cast<float>(std::cos(params_.inlier_angle_deg * kDegToRad));
  const float kf = params_.feature_weight;
  unary_.resize(n * num_labels);
  for (size_t i = 0; i < n; ++i) {
    float* u = unary_.data() + i * num_labels;
    if (f.num_points[i] == 0) {
      std::fill(u, u + num_labels, 0.f);  // no evidence: the neighbours decide
      continue;
    }
    const float a2d = f.a2d[i];
    for (size_t p = 0; p < num_planes; ++p) {
      const PlaneModel& q = hypotheses_[p];
      float cost = std::fabs(Dot(q.normal, f.centroid[i]) + q.d) / rho;
      if (Dot(q.normal, f.normal[i]) < min_cos) cost += params_.normal_mismatch_cost;
      u[p] = cost + kf * (1.f - a2d);
    }
    u[num_planes] = params_.no_plane_cost_factor + kf * a2d;
  }

  PottsEnergy energy;
  energy.num_nodes = static_cast<int>(n);
  energy.num_labels = static_cast<int>(num_labels);
  energy.unary = unary_;
  energy.offsets = sv.adjacency_offsets;
  energy.neighbors = sv.adjacency;
  energy.uniform_weight = params_.smoothness_weight;
  labels_.clear();
  const auto t0 = std::chrono::steady_clock::now();
  out->energy = expansion_.Minimize(energy, params_.max_expansion_cycles, &labels_);
  out->expansion_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  out->expansion_cycles = expansion_.last_cycles();

  // Keep planes that received supervoxels, renumbered in acceptance order.
  remap_.assign(num_planes, -1);
  for (size_t p = 0; p < num_planes; ++p) {
    hypotheses_[p].num_points = 0;
    hypotheses_[p].num_patches = 0;
  }
  for (size_t i = 0; i < n; ++i) {
    const auto l = static_cast<size_t>(labels_[i]);
    if (l == num_planes) continue;
    hypotheses_[l].num_points += f.num_points[i];
    ++hypotheses_[l].num_patches;
  }
  for (size_t p = 0; p < num_planes; ++p) {
    if (hypotheses_[p].num_patches == 0 && p >= num_fixed && hypotheses_[p].fixed_points == 0) {
      continue;
    }
    remap_[p] = static_cast<int32_t>(out->planes.size());
    out->planes.push_back(hypotheses_[p]);
  }
  for (size_t i = 0; i < n; ++i) {
    const auto l = static_cast<size_t>(labels_[i]);
    out->patch_plane[i] = l == num_planes ? -1 : remap_[l];
  }
}

}  // namespace clutterseg::optimize
