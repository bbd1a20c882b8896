#include "clutterseg/pipeline/neck_cut.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "clutterseg/core/label_scan.h"
#include "clutterseg/geometry/moments.h"
#include "clutterseg/pipeline/stage_times.h"

namespace clutterseg::pipeline {
namespace {

constexpr size_t kMaxChunks = 16;          // chunks of objects searched on the pool
constexpr int kDepthRowStep = 4;           // an object's mean depth from every fourth row
constexpr uint32_t kStep = 3;              // chamfer distance of a 4-neighbour
constexpr uint32_t kDiagonal = 4;          // and of a diagonal neighbour
constexpr uint16_t kFar = 60000;           // "no pixel of the source near"
constexpr float kOccluderDepthM = 0.01f;   // a flank pixel this far in front is an occluder
constexpr double kPlanarRmsM = 0.005;      // a part within this RMS of its plane is planar
constexpr double kOnePlaneFactor = 1.5;    // one plane fits all parts within this times
constexpr double kOnePlaneSlackM = 0.001;  // the worst part's RMS plus this

// Two-pass chamfer distance (3-4) of every pixel inside the one-pixel ring of a w x h array to
// the nearest pixel whose `dist` is 0 on entry (others kFar); the ring must be 0 or kFar and
// is not updated.
void Chamfer(int w, int h, std::vector<uint16_t>* dist) {
  uint16_t* d = dist->data();
  auto relax = [d](int i, int j, uint32_t step) {
    const uint32_t v = uint32_t{d[j]} + step;
    if (v < d[i]) d[i] = static_cast<uint16_t>(v);
  };
  for (int y = 1; y + 1 < h; ++y) {
    for (int i = y * w + 1, end = y * w + w - 1; i < end; ++i) {
      if (d[i] == 0) continue;
      relax(i, i - 1, kStep);
      relax(i, i - w, kStep);
      relax(i, i - w - 1, kDiagonal);
      relax(i, i - w + 1, kDiagonal);
    }
  }
  for (int y = h - 2; y >= 1; --y) {
    for (int i = y * w + w - 2, end = y * w; i > end; --i) {
      if (d[i] == 0) continue;
      relax(i, i + 1, kStep);
      relax(i, i + w, kStep);
      relax(i, i + w + 1, kDiagonal);
      relax(i, i + w - 1, kDiagonal);
    }
  }
}

// RMS distance (metres) of the points whose moments are `m` to their plane; infinite for
// fewer than three points.
double PlaneRms(const double* m) {
  if (m[0] < 3.0) return std::numeric_limits<double>::infinity();
  double mean[3], cov[6], vec[3], eigenvalues[3];
  geometry::MomentsCovariance(m, mean, cov);
  geometry::SmallestEigenvector(cov, vec, eigenvalues);
  return std::sqrt(std::max(0.0, eigenvalues[2]));
}

}  // namespace

NeckCutter::NeckCutter(const ObjectParams& params, core::ThreadPool* pool)
    : params_((params.ValidateOrThrow(), params)), pool_(pool) {}

int NeckCutter::Radius(float fx, uint32_t k) const {
  const Box& b = boxes_[k];
  const double z = b.z_sum / static_cast<double>(std::max(b.z_count, 1u));
  const double r = 0.5 * double{params_.neck_cut_max_width_m} * double{fx} / std::max(z, 0.01);
  return std::max(1, static_cast<int>(std::lround(r)));
}

int NeckCutter::Partition(const core::PointCloudView& cloud, uint32_t k, int radius,
                          Work* work) const {
  const Box& b = boxes_[k];
  const uint32_t label = k + 1;
  const int w = b.x1 - b.x0 + 3;
  const int h = b.y1 - b.y0 + 3;
  work->x0 = b.x0 - 1;
  work->y0 = b.y0 - 1;
  work->w = w;
  work->h = h;
  const auto n = static_cast<size_t>(w) * static_cast<size_t>(h);
  // The object's pixels (kFar); everything else, the ring and beyond the image included, is
  // outside (0). Distances stay above 0 on the object's pixels.
  work->dist.assign(n, 0);
  for (int y = 1; y + 1 < h; ++y) {
    const uint32_t* row = labels_ + static_cast<size_t>(work->y0 + y) * cloud.width + work->x0;
    for (int x = 1; x + 1 < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      if (row[x] == label) work->dist[i] = kFar;
    }
  }
  // The erosion's cores: 4-connected pixels farther than the radius from the outside.
  Chamfer(w, h, &work->dist);
  const auto core_min = static_cast<uint32_t>(kStep * radius);
  const uint16_t* dist = work->dist.data();
  work->owner.assign(n, -1);
  int32_t* owner = work->owner.data();
  work->size.clear();
  std::vector<uint32_t>& queue = work->queue;
  const int32_t offsets[4] = {-1, 1, -w, w};
  for (size_t s = 0; s < n; ++s) {
    if (owner[s] >= 0 || dist[s] <= core_min) continue;  // the outside's distance is 0
    const auto c = static_cast<int32_t>(work->size.size());
    uint32_t count = 0;
    queue.assign(1, static_cast<uint32_t>(s));
    owner[s] = c;
    while (!queue.empty()) {
      const uint32_t u = queue.back();
      queue.pop_back();
      ++count;
      for (const int32_t o : offsets) {
        const uint32_t v = u + static_cast<uint32_t>(o);
        if (owner[v] >= 0 || dist[v] <= core_min) continue;
        owner[v] = c;
        queue.push_back(v);
      }
    }
    work->size.push_back(count);
  }
  const size_t num_cores = work->size.size();
  if (num_cores < 2) return 0;
  const auto min_points = static_cast<uint32_t>(params_.min_object_points);
  const auto big = std::max<uint32_t>(
      min_points / 4,
      static_cast<uint32_t>(std::ceil(params_.neck_cut_min_share * static_cast<float>(b.count))));
  work->is_part.assign(num_cores, 0);
  size_t num_big = 0;
  for (size_t c = 0; c < num_cores; ++c) {
    if (work->size[c] >= big) {
      work->is_part[c] = 1;
      ++num_big;
    }
  }
  if (num_big < 2) return 0;

  // Every pixel of the object to the big core it reaches first (breadth first from all of
  // them, in pixel order).
  queue.clear();
  for (size_t s = 0; s < n; ++s) {
    const int32_t c = owner[s];
    if (c < 0) continue;
    if (work->is_part[static_cast<size_t>(c)]) {
      queue.push_back(static_cast<uint32_t>(s));
    } else {
      owner[s] = -1;
    }
  }
  std::fill(work->size.begin(), work->size.end(), 0u);
  for (size_t head = 0; head < queue.size(); ++head) {
    const uint32_t u = queue[head];
    const int32_t c = owner[u];
    ++work->size[static_cast<size_t>(c)];
    for (const int32_t o : offsets) {
      const uint32_t v = u + static_cast<uint32_t>(o);
      if (owner[v] >= 0 || dist[v] == 0) continue;
      owner[v] = c;
      queue.push_back(v);
    }
  }
  int parts = 0;
  for (size_t c = 0; c < num_cores; ++c) {
    if (work->is_part[c] && work->size[c] < min_points) work->is_part[c] = 0;
    parts += work->is_part[c];
  }
  return parts;
}

bool NeckCutter::Search(const core::PointCloudView& cloud, float fx, uint32_t k, Work* work) const {
  const Box& b = boxes_[k];
  if (b.count < 2 * static_cast<uint32_t>(params_.min_object_points) || b.z_count == 0) {
    return false;
  }
  const int radius = Radius(fx, k);
  if (Partition(cloud, k, radius, work) < 2) return false;
  const int w = work->w;
  const int h = work->h;
  const auto width = static_cast<size_t>(cloud.width);
  auto image_index = [&](int x, int y) {
    return static_cast<size_t>(work->y0 + y) * width + static_cast<size_t>(work->x0 + x);
  };
  auto part = [&](size_t i) {
    const int32_t c = work->owner[i];
    return c >= 0 && work->is_part[static_cast<size_t>(c)] ? c : -1;
  };

  // The cut line: pixels of a part beside a pixel of another part (never on the ring).
  work->line.clear();
  work->depths.clear();
  int lx0 = w, ly0 = h, lx1 = -1, ly1 = -1;
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      const int32_t c = part(i);
      if (c < 0) continue;
      const int32_t l = part(i - 1), r = part(i + 1), u = part(i - w), d = part(i + w);
      if ((l >= 0 && l != c) || (r >= 0 && r != c) || (u >= 0 && u != c) || (d >= 0 && d != c)) {
        const size_t p = image_index(x, y);
        work->line.push_back(static_cast<uint32_t>(p));
        if (std::isfinite(cloud.xyz[p].z)) work->depths.push_back(cloud.xyz[p].z);
        lx0 = std::min(lx0, x);
        ly0 = std::min(ly0, y);
        lx1 = std::max(lx1, x);
        ly1 = std::max(ly1, y);
      }
    }
  }
  if (work->depths.empty()) return false;
  const auto mid = work->depths.begin() + static_cast<std::ptrdiff_t>(work->depths.size() / 2);
  std::nth_element(work->depths.begin(), mid, work->depths.end());
  const float line_z = *mid;

  // Occlusion: the valid pixels outside the object within twice the radius of the line (a
  // box around the line's, with a ring), and how many lie in front of it.
  const int reach = 2 * radius;
  const int fx0 = std::max(0, work->x0 + lx0 - reach) - 1;
  const int fy0 = std::max(0, work->y0 + ly0 - reach) - 1;
  const int fw = std::min(cloud.width - 1, work->x0 + lx1 + reach) - fx0 + 2;
  const int fh = std::min(cloud.height - 1, work->y0 + ly1 + reach) - fy0 + 2;
  work->flank.assign(static_cast<size_t>(fw) * static_cast<size_t>(fh), kFar);
  for (const uint32_t p : work->line) {
    const int x = static_cast<int>(p % width) - fx0;
    const int y = static_cast<int>(p / width) - fy0;
    work->flank[static_cast<size_t>(y) * fw + x] = 0;
  }
  Chamfer(fw, fh, &work->flank);
  const auto flank_max = static_cast<uint32_t>(kStep * reach);
  const uint32_t label = k + 1;
  uint32_t flank = 0, in_front = 0;
  for (int y = 1; y + 1 < fh; ++y) {
    for (int x = 1; x + 1 < fw; ++x) {
      if (work->flank[static_cast<size_t>(y) * fw + x] > flank_max) continue;
      const size_t p = static_cast<size_t>(fy0 + y) * width + static_cast<size_t>(fx0 + x);
      const float z = cloud.xyz[p].z;
      if (labels_[p] == label || !std::isfinite(z)) continue;
      ++flank;
      in_front += z < line_z - kOccluderDepthM ? 1u : 0u;
    }
  }
  if (flank > 0 && static_cast<float>(in_front) >
                       params_.neck_cut_max_occluded_share * static_cast<float>(flank)) {
    return false;
  }

  // One plane through every part: one surface around an occluder.
  const size_t num_cores = work->size.size();
  double moments[geometry::kNumMoments] = {};
  double worst = 0.0;
  for (size_t c = 0; c < num_cores; ++c) {
    if (!work->is_part[c]) continue;
    double m[geometry::kNumMoments] = {};
    for (int y = 1; y + 1 < h; ++y) {
      for (int x = 1; x + 1 < w; ++x) {
        const core::Vec3f& p = cloud.xyz[image_index(x, y)];
        if (work->owner[static_cast<size_t>(y) * w + x] == static_cast<int32_t>(c) &&
            core::IsValid(p)) {
          geometry::AddToMoments(p, m);
        }
      }
    }
    for (int j = 0; j < geometry::kNumMoments; ++j) moments[j] += m[j];
    worst = std::max(worst, PlaneRms(m));
  }
  return !(worst <= kPlanarRmsM && PlaneRms(moments) <= kOnePlaneFactor * worst + kOnePlaneSlackM);
}

uint32_t NeckCutter::Compute(const core::PointCloudView& cloud,
                             const core::CameraIntrinsics& intrinsics, SegmentationResult* result) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto num_objects = static_cast<uint32_t>(result->objects.size());
  std::vector<uint32_t>& labels = result->labels.data;
  const size_t size = labels.size();
  if (params_.neck_cut_max_width_m <= 0.f || num_objects == 0 || !cloud.organized() ||
      cloud.xyz.size() != size ||
      size != static_cast<size_t>(cloud.width) * static_cast<size_t>(cloud.height)) {
    return 0;
  }
  labels_ = labels.data();
  const auto fx = static_cast<float>(intrinsics.fx);

  // Each object's box, pixel count and mean depth (of every fourth row), by runs of one label
  // along each row (blocks of eight background pixels skipped).
  boxes_.assign(num_objects, Box{cloud.width, cloud.height, -1, -1, 0u, 0u, 0.0});
  const auto width = static_cast<size_t>(cloud.width);
  for (int y = 0; y < cloud.height; ++y) {
    const uint32_t* row = labels_ + static_cast<size_t>(y) * width;
    const core::Vec3f* row_xyz = cloud.xyz.data() + static_cast<size_t>(y) * width;
    const bool sample_z = y % kDepthRowStep == 0;
    size_t x = 0;
    while (x < width) {
      if (x + 8 <= width && core::AllZero8(row + x)) {
        x += 8;
        continue;
      }
      const uint32_t l = row[x];
      size_t end = x + 1;
      while (end < width && row[end] == l) ++end;
      if (l - 1 < num_objects) {
        Box& b = boxes_[l - 1];
        b.x0 = std::min(b.x0, static_cast<int>(x));
        b.x1 = std::max(b.x1, static_cast<int>(end - 1));
        b.y0 = std::min(b.y0, y);
        b.y1 = y;
        b.count += static_cast<uint32_t>(end - x);
        for (size_t i = x; sample_z && i < end; ++i) {
          if (!std::isfinite(row_xyz[i].z)) continue;
          b.z_sum += row_xyz[i].z;
          ++b.z_count;
        }
      }
      x = end;
    }
  }

  const size_t grain = (num_objects + kMaxChunks - 1) / kMaxChunks;
  if (work_.size() < kMaxChunks) work_.resize(kMaxChunks);
  cut_.assign(num_objects, 0);
  core::ForChunks(pool_, num_objects, grain, [&](size_t begin, size_t end) {
    Work* work = &work_[begin / grain];
    for (size_t k = begin; k < end; ++k) {
      cut_[k] = Search(cloud, fx, static_cast<uint32_t>(k), work) ? 1 : 0;
    }
  });

  // The parts other than the largest become objects of their own, in object order, within
  // max_objects. The search keeps no partition per object (its chunks share buffers), so the
  // few objects cut are partitioned again here; labels of other objects do not change what
  // Partition reads.
  uint32_t next = num_objects;
  uint32_t num_cut = 0;
  Work* work = &work_[0];
  for (uint32_t k = 0; k < num_objects; ++k) {
    if (!cut_[k]) continue;
    Partition(cloud, k, Radius(fx, k), work);
    const size_t num_cores = work->size.size();
    size_t largest = num_cores;
    for (size_t c = 0; c < num_cores; ++c) {
      if (work->is_part[c] && (largest == num_cores || work->size[c] > work->size[largest])) {
        largest = c;
      }
    }
    // New labels of the cores (0: keep the object's).
    std::vector<uint32_t>& new_label = work->queue;
    new_label.assign(num_cores, 0u);
    for (size_t c = 0; c < num_cores; ++c) {
      if (!work->is_part[c] || c == largest) continue;
      if (next >= static_cast<uint32_t>(params_.max_objects)) break;
      new_label[c] = ++next;
    }
    ++num_cut;
    for (int y = 1; y + 1 < work->h; ++y) {
      for (int x = 1; x + 1 < work->w; ++x) {
        const int32_t c = work->owner[static_cast<size_t>(y) * work->w + x];
        if (c >= 0 && new_label[static_cast<size_t>(c)] != 0) {
          labels[static_cast<size_t>(work->y0 + y) * width + static_cast<size_t>(work->x0 + x)] =
              new_label[static_cast<size_t>(c)];
        }
      }
    }
  }
  if (num_cut > 0) {
    result->objects.assign(core::RenumberInFirstPixelOrder(&labels, next, &relabel_), Object{});
  }
  labels_ = nullptr;
  result->times[Stage::kRefine] +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return num_cut;
}

}  // namespace clutterseg::pipeline
