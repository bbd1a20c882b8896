#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"

namespace clutterseg::supervoxel::testing {

/// An axis-aligned box standing on the table (world frame: z up, table at z = 0), metres.
struct Box {
  double x0, y0, x1, y1, height;
};

/// A rendered synthetic scene: the organized cloud (from a millimetre depth image through
/// core::DepthToPointCloud) and, per pixel, which surface was hit: -1 none, 0 the table,
/// 1 + 6 * box + face for box faces.
struct Scene {
  core::PointCloud cloud;
  std::vector<int> surface;
};

/// Renders a table with boxes seen from a camera at `camera_height_m` above the table and
/// `camera_back_m` behind the origin, looking at the origin. `noise_mm` adds Gaussian depth
/// noise (seeded, deterministic). Colour: table grey, each box a different colour.
inline Scene RenderTableScene(const std::vector<Box>& boxes, double camera_back_m = 0.8,
                              double camera_height_m = 0.7, double noise_mm = 0.0,
                              const core::CameraIntrinsics& k = core::DefaultKinectIntrinsics(),
                              double table_half_size_m = 0.6) {
  // Camera axes in the world frame: right, down, forward.
  const double cx = 0.0, cy = -camera_back_m, cz = camera_height_m;
  double f[3] = {-cx, -cy, -cz};
  const double fl = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  for (double& c : f) c /= fl;
  double r[3] = {f[1], -f[0], 0.0};  // f x (0, 0, 1)
  const double rl = std::sqrt(r[0] * r[0] + r[1] * r[1]);
  for (double& c : r) c /= rl;
  const double d[3] = {f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2],
                       f[0] * r[1] - f[1] * r[0]};  // f x r

  core::DepthImage depth(k.width, k.height, 0);
  core::ColorImage color(k.width, k.height);
  Scene scene;
  scene.surface.assign(static_cast<size_t>(k.width) * k.height, -1);
  std::mt19937 rng(12345);
  std::normal_distribution<double> noise(0.0, noise_mm);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const double dc[3] = {(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0};
      const double dw[3] = {r[0] * dc[0] + d[0] * dc[1] + f[0] * dc[2],
                            r[1] * dc[0] + d[1] * dc[1] + f[1] * dc[2],
                            r[2] * dc[0] + d[2] * dc[1] + f[2] * dc[2]};
      double best_t = 1e9;
      int best_surface = -1;
      // Table plane z = 0.
      if (dw[2] < 0.0) {
        const double t = -cz / dw[2];
        const double px = cx + t * dw[0], py = cy + t * dw[1];
        if (std::fabs(px) <= table_half_size_m && std::fabs(py) <= table_half_size_m) {
          best_t = t;
          best_surface = 0;
        }
      }
      // Boxes: slab intersection, the entry face is the hit face.
      for (size_t b = 0; b < boxes.size(); ++b) {
        const double lo[3] = {boxes[b].x0, boxes[b].y0, 0.0};
        const double hi[3] = {boxes[b].x1, boxes[b].y1, boxes[b].height};
        const double o[3] = {cx, cy, cz};
        double t_in = -1e9, t_out = 1e9;
        int face = -1;
        for (int a = 0; a < 3; ++a) {
          if (std::fabs(dw[a]) < 1e-12) {
            if (o[a] < lo[a] || o[a] > hi[a]) t_in = 1e9;
            continue;
          }
          double t0 = (lo[a] - o[a]) / dw[a], t1 = (hi[a] - o[a]) / dw[a];
          int f0 = 2 * a, f1 = 2 * a + 1;
          if (t0 > t1) {
            std::swap(t0, t1);
            std::swap(f0, f1);
          }
          if (t0 > t_in) {
            t_in = t0;
            face = f0;
          }
          t_out = std::min(t_out, t1);
        }
        if (t_in <= t_out && t_in > 0.0 && t_in < best_t) {
          best_t = t_in;
          best_surface = 1 + 6 * static_cast<int>(b) + face;
        }
      }
      if (best_surface < 0) continue;
      const size_t i = static_cast<size_t>(v) * k.width + u;
      double z_mm = best_t * 1000.0 + (noise_mm > 0.0 ? noise(rng) : 0.0);
      depth.data[i] = static_cast<uint16_t>(std::clamp(std::lround(z_mm), 1l, 65535l));
      scene.surface[i] = best_surface;
      const uint8_t shade =
          static_cast<uint8_t>(best_surface == 0 ? 128 : 40 + 30 * (best_surface % 7));
      color.data[i] = core::Rgb8{shade, static_cast<uint8_t>(255 - shade), 90};
    }
  }
  core::DepthToPointCloud(depth, k, &color, &scene.cloud);
  return scene;
}

/// Three boxes of different sizes on the table.
inline std::vector<Box> DefaultBoxes() {
  return {{-0.25, -0.05, -0.10, 0.10, 0.12},
          {0.02, -0.12, 0.14, 0.02, 0.20},
          {0.10, 0.15, 0.30, 0.25, 0.08}};
}

/// A fronto-parallel plane at depth `z_m` covering |x|, |y| <= half_size_m, as an exact
/// (unrounded) organized cloud with the given intrinsics.
inline core::PointCloud FrontalPlane(double z_m, double half_size_m,
                                     const core::CameraIntrinsics& k) {
  core::PointCloud cloud;
  cloud.width = k.width;
  cloud.height = k.height;
  cloud.xyz.assign(static_cast<size_t>(k.width) * k.height,
                   core::Vec3f{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth});
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const double x = (u - k.cx) / k.fx * z_m, y = (v - k.cy) / k.fy * z_m;
      if (std::fabs(x) > half_size_m || std::fabs(y) > half_size_m) continue;
      cloud.xyz[static_cast<size_t>(v) * k.width + u] =
          core::Vec3f{static_cast<float>(x), static_cast<float>(y), static_cast<float>(z_m)};
    }
  }
  return cloud;
}

}  // namespace clutterseg::supervoxel::testing
