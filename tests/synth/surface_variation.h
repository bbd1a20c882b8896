#pragma once

// Surface variation of small surface patches in organized clouds: the statistic that compares
// the synthetic sensor's noise texture with real Kinect frames.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Eigenvalues>

#include "clutterseg/core/point_cloud.h"

namespace clutterseg::synth::testing {

struct PatchOptions {
  double diameter_m{0.03};  ///< patch: points within diameter / 2 (3-D) of the centre point
  int stride_px{6};         ///< patch centres on this pixel grid
  double min_depth_m{0.9};  ///< centre depth range
  double max_depth_m{1.1};
  int min_points{30};
  double focal_px{525.0};  ///< to size the pixel window
};

/// Surface variation l3 / (l1 + l2 + l3) (eigenvalues of the 3-D covariance, l3 smallest) of
/// every patch of `cloud` whose centre lies in the depth range and whose neighbourhood holds
/// only points with `in_surface[i]` (invalid points are skipped; a patch touching a valid point
/// outside the surface is discarded). Appends one value per patch to `out`.
inline void CollectSurfaceVariation(const core::PointCloud& cloud,
                                    const std::vector<uint8_t>& in_surface, const PatchOptions& opt,
                                    std::vector<double>* out) {
  const double r = 0.5 * opt.diameter_m;
  const int w = cloud.width;
  const int h = cloud.height;
  auto valid = [&](size_t i) { return std::isfinite(cloud.xyz[i].z); };
  for (int v = 0; v < h; v += opt.stride_px) {
    for (int u = 0; u < w; u += opt.stride_px) {
      const size_t c = static_cast<size_t>(v) * w + u;
      if (!valid(c) || !in_surface[c]) continue;
      const core::Vec3f pc = cloud.xyz[c];
      if (pc.z < opt.min_depth_m || pc.z > opt.max_depth_m) continue;
      const int half = static_cast<int>(std::ceil(opt.focal_px * r / pc.z)) + 1;
      if (u - half < 0 || v - half < 0 || u + half >= w || v + half >= h) continue;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      Eigen::Matrix3d sum2 = Eigen::Matrix3d::Zero();
      int n = 0;
      bool foreign = false;
      for (int dv = -half; dv <= half && !foreign; ++dv) {
        for (int du = -half; du <= half; ++du) {
          const size_t i = static_cast<size_t>(v + dv) * w + (u + du);
          if (!valid(i)) continue;
          const core::Vec3f p = cloud.xyz[i];
          const Eigen::Vector3d d(p.x - pc.x, p.y - pc.y, p.z - pc.z);
          if (d.norm() > r) continue;
          if (!in_surface[i]) {
            foreign = true;
            break;
          }
          sum += d;
          sum2 += d * d.transpose();
          ++n;
        }
      }
      if (foreign || n < opt.min_points) continue;
      const Eigen::Vector3d mean = sum / n;
      const Eigen::Matrix3d cov = sum2 / n - mean * mean.transpose();
      const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvalues();
      const double total = ev.sum();
      if (total > 0.0) out->push_back(std::max(0.0, ev(0)) / total);
    }
  }
}

inline double Median(std::vector<double> values) {
  if (values.empty()) return std::nan("");
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  return values[mid];
}

}  // namespace clutterseg::synth::testing
