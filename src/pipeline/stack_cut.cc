#include "clutterseg/pipeline/stack_cut.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "clutterseg/core/label_scan.h"
#include "clutterseg/geometry/moments.h"
#include "clutterseg/pipeline/stage_times.h"

namespace clutterseg::pipeline {
namespace {

constexpr float kUprightMaxCos = 0.3f;  // |n . up| below this: an upright face
constexpr int kMaxFaces = 3;            // faces searched per object
constexpr float kScanStepM = 0.002f;    // splits tried every 2 mm of a face's height
constexpr float kMinSideSpanM = 0.01f;  // each side spans at least this height
constexpr float kBandM = 0.008f;        // the bands beside the split that must step
constexpr size_t kMinBandPoints = 30;   // points in each band
constexpr float kMinBandShare = 0.7f;   // the bands step by this share of the step
constexpr float kCutMarginM = 0.003f;   // the upper part starts this far above the split
constexpr float kCoarseShare = 0.5f;    // the bins' first look asks this share of the step
constexpr float kMadToSigma = 1.4826f;  // robust standard deviation from the MAD
constexpr int kAzimuthBins = 360;
constexpr size_t kMaxChunks = 16;    // chunks of objects searched on the pool
constexpr int32_t kNotUpright = -2;  // Work::sv_entry of a supervoxel that is not upright

// Median of v (reordered), the mean of the two middle values for an even count.
float Median(std::vector<float>* v) {
  const size_t n = v->size();
  const size_t m = n / 2;
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(m), v->end());
  const float hi = (*v)[m];
  if (n % 2 == 1) return hi;
  const float lo = *std::max_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(m));
  return 0.5f * (lo + hi);
}

// Percentile q (0..1) of v (reordered), linearly interpolated between order statistics.
float Percentile(std::vector<float>* v, float q) {
  const float pos = q * static_cast<float>(v->size() - 1);
  const auto i = static_cast<size_t>(pos);
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(i), v->end());
  const float lo = (*v)[i];
  if (i + 1 >= v->size()) return lo;
  const float hi = *std::min_element(v->begin() + static_cast<std::ptrdiff_t>(i) + 1, v->end());
  return lo + (pos - static_cast<float>(i)) * (hi - lo);
}

// Width of the 5..95 % range of the `n` values at `e`.
float Spread(const float* e, size_t n, std::vector<float>* tmp) {
  tmp->assign(e, e + n);
  const float lo = Percentile(tmp, 0.05f);
  const float hi = Percentile(tmp, 0.95f);
  return hi - lo;
}

}  // namespace

bool StackCutter::Cut::Above(const core::Vec3f& p) const {
  return nx * p.x + ny * p.y + nz * p.z + d > height + kCutMarginM;
}

StackCutter::StackCutter(const ObjectParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

StackCutter::Cut StackCutter::Search(const core::PointCloudView& cloud,
                                     const supervoxel::Supervoxels& sv,
                                     const std::vector<Plane>& planes, uint32_t k,
                                     Work* work) const {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Cut cut{nan, 0.f, 0.f, 0.f, 0.f};
  const uint32_t* px = pixels_.data() + offsets_[k];
  const size_t count = offsets_[k + 1] - offsets_[k];
  const auto min_points = static_cast<size_t>(params_.min_object_points);
  if (count < 3 * min_points) return cut;
  const core::Vec3f* xyz = cloud.xyz.data();

  // The support: the nearest support plane below the object's centroid (normals point to the
  // camera, so "below" is a positive signed distance of the centroid), the centroid of every
  // sixteenth point.
  double sx = 0.0, sy = 0.0, sz = 0.0;
  size_t summed = 0;
  for (size_t j = 0; j < count; j += 16, ++summed) {
    sx += xyz[px[j]].x;
    sy += xyz[px[j]].y;
    sz += xyz[px[j]].z;
  }
  const double inv = 1.0 / static_cast<double>(summed);
  float best_dist = std::numeric_limits<float>::infinity();
  const Plane* support = nullptr;
  for (const Plane& p : planes) {
    if (!p.is_support) continue;
    const auto dist = static_cast<float>(p.normal.x * sx * inv + p.normal.y * sy * inv +
                                         p.normal.z * sz * inv + p.d);
    if (dist > 0.f && dist < best_dist) {
      best_dist = dist;
      support = &p;
    }
  }
  if (support == nullptr) return cut;
  const Eigen::Vector3f up(support->normal.x, support->normal.y, support->normal.z);
  const float d0 = support->d;

  // The upright points: those of supervoxels whose normal lies within 17.5 degrees of the
  // support plane, with the direction their supervoxel faces across the support's normal as
  // an azimuth in a basis (e1, e2) of the plane.
  const Eigen::Vector3f e1 = up.unitOrthogonal();
  const Eigen::Vector3f e2 = up.cross(e1);
  constexpr float kPi = std::numbers::pi_v<float>;
  // Each upright supervoxel of the object is an entry (its direction, azimuth bin, points),
  // each upright point a pixel and its entry.
  work->up_pixel.clear();
  work->up_entry.clear();
  work->entries.clear();
  work->touched.clear();
  work->sv_entry.resize(sv.normal.size(), -1);
  int32_t last_s = -1;
  int32_t last_entry = -1;
  for (size_t j = 0; j < count; ++j) {
    const int32_t s = sv.pixel_label[px[j]];
    if (s < 0) continue;
    if (s != last_s) {
      last_s = s;
      int32_t& entry = work->sv_entry[static_cast<size_t>(s)];
      if (entry == -1) {
        work->touched.push_back(s);
        const core::Vec3f& nv = sv.normal[static_cast<size_t>(s)];
        const Eigen::Vector3f n(nv.x, nv.y, nv.z);
        const float c = n.dot(up);
        if (std::abs(c) < kUprightMaxCos) {
          const Eigen::Vector3f dir = (n - c * up).normalized();
          const float azimuth = std::atan2(dir.dot(e2), dir.dot(e1));
          const int bin =
              static_cast<int>(std::floor((azimuth + kPi) / (2.f * kPi) * kAzimuthBins));
          entry = static_cast<int32_t>(work->entries.size());
          work->entries.push_back(
              Entry{dir.x(), dir.y(), dir.z(), std::clamp(bin, 0, kAzimuthBins - 1), 0, 0});
        } else {
          entry = kNotUpright;
        }
      }
      last_entry = entry;
    }
    if (last_entry < 0) continue;
    ++work->entries[static_cast<size_t>(last_entry)].points;
    work->up_pixel.push_back(px[j]);
    work->up_entry.push_back(static_cast<uint32_t>(last_entry));
  }
  // sv_entry back to -1 for the next object: only the supervoxels met here were set.
  for (int32_t t : work->touched) work->sv_entry[static_cast<size_t>(t)] = -1;
  const size_t num_upright = work->up_pixel.size();
  if (num_upright < 2 * min_points) return cut;

  const float cos_face = std::cos(params_.stack_cut_face_angle_deg * kPi / 180.f);
  const int window = static_cast<int>(std::floor(params_.stack_cut_face_angle_deg));
  work->hist.resize(kAzimuthBins);
  float best_z = 0.f;

  for (int f = 0; f < kMaxFaces; ++f) {
    // The most common direction among the points not yet in a face.
    std::fill(work->hist.begin(), work->hist.end(), 0);
    size_t left = 0;
    for (const Entry& en : work->entries) {
      if (en.face != 0) continue;
      left += en.points;
      work->hist[static_cast<size_t>(en.bin)] += static_cast<int>(en.points);
    }
    if (left < 2 * min_points) break;
    int best_bin = 0;
    int best_count = -1;
    for (int c = 0; c < kAzimuthBins; ++c) {
      int sum = 0;
      for (int o = -window; o <= window; ++o) {
        sum += work->hist[static_cast<size_t>((c + o + kAzimuthBins) % kAzimuthBins)];
      }
      if (sum > best_count) {
        best_count = sum;
        best_bin = c;
      }
    }
    const float az = (static_cast<float>(best_bin) + 0.5f) / kAzimuthBins * 2.f * kPi - kPi;
    const Eigen::Vector3f dir = std::cos(az) * e1 + std::sin(az) * e2;
    // The supervoxels facing that way (within the face angle) are this face's.
    const uint8_t face_mark = static_cast<uint8_t>(f + 1);
    for (Entry& en : work->entries) {
      if (en.face != 0) continue;
      if (en.x * dir.x() + en.y * dir.y() + en.z * dir.z() > cos_face) en.face = face_mark;
    }
    work->face.clear();
    for (size_t j = 0; j < num_upright; ++j) {
      if (work->entries[work->up_entry[j]].face == face_mark)
        work->face.push_back(work->up_pixel[j]);
    }
    const size_t n = work->face.size();
    if (n < 2 * min_points) continue;

    // The face's normal: its points' plane, turned across the support's normal.
    double m[geometry::kNumMoments] = {};
    for (uint32_t i : work->face) geometry::AddToMoments(xyz[i], m);
    double mean[3], cov[6], vec[3], eigenvalues[3];
    geometry::MomentsCovariance(m, mean, cov);
    geometry::SmallestEigenvector(cov, vec, eigenvalues);
    Eigen::Vector3f nf(static_cast<float>(vec[0]), static_cast<float>(vec[1]),
                       static_cast<float>(vec[2]));
    nf -= nf.dot(up) * up;
    if (!(nf.norm() > 1e-6f)) continue;
    nf.normalize();
    const Eigen::Vector3f ax = up.cross(nf);
    // Height, offset along the face's normal and position across it of each face point.
    work->h.resize(n);
    work->r.resize(n);
    work->e.resize(n);
    float h_first = std::numeric_limits<float>::infinity();
    float h_last = -h_first;
    for (size_t j = 0; j < n; ++j) {
      const core::Vec3f& p = xyz[work->face[j]];
      work->h[j] = up.x() * p.x + up.y() * p.y + up.z() * p.z + d0;
      work->r[j] = nf.x() * p.x + nf.y() * p.y + nf.z() * p.z;
      work->e[j] = ax.x() * p.x + ax.y() * p.y + ax.z() * p.z;
      h_first = std::min(h_first, work->h[j]);
      h_last = std::max(h_last, work->h[j]);
    }

    // A first look in bins of the scan step: the splits whose bands' mean offsets step by at
    // least half the smallest step (the exact test below asks 0.7 of it of the medians).
    const auto num_bins = static_cast<size_t>((h_last - h_first) / kScanStepM) + 1;
    work->bin_sum.assign(num_bins, 0.0);
    work->bin_count.assign(num_bins, 0u);
    for (size_t j = 0; j < n; ++j) {
      const auto b =
          std::min(num_bins - 1, static_cast<size_t>((work->h[j] - h_first) / kScanStepM));
      work->bin_sum[b] += work->r[j];
      ++work->bin_count[b];
    }
    constexpr size_t kSpanBins = static_cast<size_t>(kMinSideSpanM / kScanStepM + 0.5f);
    constexpr size_t kBandBins = static_cast<size_t>(kBandM / kScanStepM + 0.5f);
    work->candidates.clear();
    for (size_t b = kSpanBins; b + kSpanBins <= num_bins; ++b) {
      double s_lo = 0.0, s_hi = 0.0;
      uint32_t c_lo = 0, c_hi = 0;
      for (size_t o = 0; o < kBandBins; ++o) {
        if (b >= o + 1) {
          s_lo += work->bin_sum[b - o - 1];
          c_lo += work->bin_count[b - o - 1];
        }
        if (b + o < num_bins) {
          s_hi += work->bin_sum[b + o];
          c_hi += work->bin_count[b + o];
        }
      }
      if (c_lo < kMinBandPoints || c_hi < kMinBandPoints) continue;
      const double coarse = s_hi / c_hi - s_lo / c_lo;
      if (std::abs(coarse) < kCoarseShare * params_.stack_cut_min_step_m) continue;
      work->candidates.push_back(h_first + static_cast<float>(b) * kScanStepM);
    }
    if (work->candidates.empty()) continue;

    // The exact test at those splits, on the face's points ordered by height.
    work->order.resize(n);
    for (size_t j = 0; j < n; ++j) work->order[j] = static_cast<uint32_t>(j);
    std::sort(work->order.begin(), work->order.end(), [&](uint32_t x, uint32_t y) {
      return work->h[x] < work->h[y] || (work->h[x] == work->h[y] && x < y);
    });
    work->hs.resize(n);
    work->rs.resize(n);
    work->es.resize(n);
    for (size_t j = 0; j < n; ++j) {
      work->hs[j] = work->h[work->order[j]];
      work->rs[j] = work->r[work->order[j]];
      work->es[j] = work->e[work->order[j]];
    }
    const float* hs = work->hs.data();
    const float* rs = work->rs.data();
    const float* es = work->es.data();
    const auto below = [&](float t) {
      return static_cast<size_t>(std::lower_bound(hs, hs + n, t) - hs);
    };
    for (float h_split : work->candidates) {
      const size_t i = below(h_split);
      if (i < min_points || n - i < min_points) continue;
      if (h_split - hs[0] < kMinSideSpanM || hs[n - 1] - h_split < kMinSideSpanM) continue;
      // The step is sharp: the bands right beside the split step by most of the step between
      // the two sides.
      const size_t band_lo = below(h_split - kBandM);
      const size_t band_hi = below(h_split + kBandM);
      if (i - band_lo < kMinBandPoints || band_hi - i < kMinBandPoints) continue;
      work->a.assign(rs + band_lo, rs + i);
      work->b.assign(rs + i, rs + band_hi);
      const float local = Median(&work->b) - Median(&work->a);
      if (std::abs(local) < kMinBandShare * params_.stack_cut_min_step_m) continue;
      // The two sides' offsets: medians, the step between them, their robust noise.
      work->a.assign(rs, rs + i);
      work->b.assign(rs + i, rs + n);
      const float ma = Median(&work->a);
      const float mb = Median(&work->b);
      const float step = mb - ma;
      if (std::abs(step) < params_.stack_cut_min_step_m ||
          std::abs(step) > params_.stack_cut_max_step_m) {
        continue;
      }
      if (std::abs(local) < kMinBandShare * std::abs(step) || (local > 0.f) != (step > 0.f)) {
        continue;
      }
      for (float& x : work->a) x = std::abs(x - ma);
      for (float& x : work->b) x = std::abs(x - mb);
      const float sa = kMadToSigma * Median(&work->a);
      const float sb = kMadToSigma * Median(&work->b);
      if (std::max(sa, sb) > params_.stack_cut_max_face_noise_m) continue;
      const float sigma = std::max({sa, sb, 1e-4f});
      const float z =
          std::abs(step) /
          (sigma * std::sqrt(1.f / static_cast<float>(i) + 1.f / static_cast<float>(n - i)));
      if (z < params_.stack_cut_min_significance || z <= best_z) continue;
      // Both sides wide enough across the face.
      if (Spread(es, i, &work->tmp) < params_.stack_cut_min_face_width_m ||
          Spread(es + i, n - i, &work->tmp) < params_.stack_cut_min_face_width_m) {
        continue;
      }
      // No bend across the face: a parabola through the offsets (each side less its median)
      // against the position across, whose sagitta over the face's width is the bend.
      double e_mean = 0.0;
      for (size_t j = 0; j < n; ++j) e_mean += es[j];
      e_mean /= static_cast<double>(n);
      Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
      Eigen::Vector3d atb = Eigen::Vector3d::Zero();
      for (size_t j = 0; j < n; ++j) {
        const double x = es[j] - e_mean;
        const double y = rs[j] - (j < i ? ma : mb);
        const Eigen::Vector3d row(x * x, x, 1.0);
        ata += row * row.transpose();
        atb += row * y;
      }
      const double bend = ata.ldlt().solve(atb)(0);
      const float width = Spread(es, n, &work->tmp);
      if (std::abs(bend) * 0.25 * width * width > params_.stack_cut_max_face_sag_m) continue;
      best_z = z;
      cut = Cut{h_split, up.x(), up.y(), up.z(), d0};
    }
  }
  if (std::isnan(cut.height)) return cut;
  // Both parts keep enough points.
  size_t upper = 0;
  for (size_t j = 0; j < count; ++j) upper += cut.Above(xyz[px[j]]) ? 1 : 0;
  if (upper < min_points || count - upper < min_points) cut.height = nan;
  return cut;
}

uint32_t StackCutter::Compute(const core::PointCloudView& cloud, const supervoxel::Supervoxels& sv,
                              SegmentationResult* result) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto num_objects = static_cast<uint32_t>(result->objects.size());
  std::vector<uint32_t>& labels = result->labels.data;
  const size_t size = labels.size();
  // The supervoxels label the same points (the working cloud's layout is the input's).
  if (params_.stack_cut_min_step_m <= 0.f || num_objects == 0 || sv.pixel_label.size() != size ||
      cloud.xyz.size() != size) {
    return 0;
  }

  // Each object's pixels, in pixel order (a counting sort on the labels).
  offsets_.assign(num_objects + 2, 0u);
  const uint32_t* label = labels.data();
  core::ForEachLabelled(label, label, size, [&](size_t i) {
    if (label[i] - 1 < num_objects) ++offsets_[label[i] + 1];
  });
  for (uint32_t k = 1; k <= num_objects + 1; ++k) offsets_[k] += offsets_[k - 1];
  pixels_.resize(offsets_[num_objects + 1]);
  fill_.assign(offsets_.begin(), offsets_.end() - 1);  // fill_[l]: next slot of label l
  core::ForEachLabelled(label, label, size, [&](size_t i) {
    if (label[i] - 1 < num_objects) pixels_[fill_[label[i]]++] = static_cast<uint32_t>(i);
  });
  // offsets_[k] .. offsets_[k + 1] are now label k + 1's pixels: shift to index by object.
  offsets_.erase(offsets_.begin());

  // At most kMaxChunks chunks of objects, each with its own work buffers (a Search leaves
  // them ready for the next object), so their memory does not grow with the object count.
  const size_t grain = (num_objects + kMaxChunks - 1) / kMaxChunks;
  if (work_.size() < kMaxChunks) work_.resize(kMaxChunks);
  cuts_.resize(num_objects);
  core::ForChunks(pool_, num_objects, grain, [&](size_t begin, size_t end) {
    Work* work = &work_[begin / grain];
    for (size_t k = begin; k < end; ++k) {
      cuts_[k] = Search(cloud, sv, result->planes, static_cast<uint32_t>(k), work);
    }
  });

  // The upper parts become objects of their own, in object order, within max_objects.
  uint32_t next = num_objects;
  uint32_t num_cuts = 0;
  for (uint32_t k = 0; k < num_objects; ++k) {
    if (std::isnan(cuts_[k].height)) continue;
    if (next >= static_cast<uint32_t>(params_.max_objects)) break;
    ++next;
    ++num_cuts;
    const uint32_t* px = pixels_.data() + offsets_[k];
    for (size_t j = 0, end = offsets_[k + 1] - offsets_[k]; j < end; ++j) {
      if (cuts_[k].Above(cloud.xyz[px[j]])) labels[px[j]] = next;
    }
  }
  if (num_cuts > 0) {
    // Ids in the order of each object's first pixel.
    result->objects.assign(core::RenumberInFirstPixelOrder(&labels, next, &relabel_), Object{});
  }
  result->times[Stage::kRefine] +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return num_cuts;
}

}  // namespace clutterseg::pipeline
