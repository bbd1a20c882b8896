#include "tests/graph/synthetic_tiles.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <tuple>

namespace clutterseg::graph::testing {
namespace {

struct Frame {
  double x[3], y[3], z[3];  // camera axes in world coordinates
  double origin[3];
};

Frame CameraFrame(const TabletopScene& s) {
  const double p = s.pitch_deg * std::numbers::pi / 180.0;
  Frame f{};
  f.x[0] = 1;
  f.x[1] = 0;
  f.x[2] = 0;
  f.y[0] = 0;
  f.y[1] = -std::sin(p);
  f.y[2] = -std::cos(p);
  f.z[0] = 0;
  f.z[1] = std::cos(p);
  f.z[2] = -std::sin(p);
  f.origin[0] = 0;
  f.origin[1] = 0;
  f.origin[2] = s.camera_height_m;
  return f;
}

// World vector -> camera coordinates (rotation only).
core::Vec3f ToCamera(const Frame& f, const double w[3]) {
  auto dot = [](const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  };
  return core::Vec3f{static_cast<float>(dot(f.x, w)), static_cast<float>(dot(f.y, w)),
                     static_cast<float>(dot(f.z, w))};
}

}  // namespace

void TablePlane(const TabletopScene& s, core::Vec3f* normal, float* d) {
  const Frame f = CameraFrame(s);
  const double up[3] = {0, 0, 1};
  *normal = ToCamera(f, up);
  *d = static_cast<float>(s.camera_height_m);
}

void WallPlane(const TabletopScene& s, core::Vec3f* normal, float* d) {
  const Frame f = CameraFrame(s);
  const double back[3] = {0, -1, 0};
  *normal = ToCamera(f, back);
  *d = static_cast<float>(s.wall_distance_m);
}

void Render(const TabletopScene& s, core::PointCloud* cloud, std::vector<int32_t>* surface) {
  const Frame f = CameraFrame(s);
  cloud->width = s.width;
  cloud->height = s.height;
  cloud->xyz.assign(static_cast<size_t>(s.width) * s.height,
                    core::Vec3f{core::kInvalidDepth, core::kInvalidDepth, core::kInvalidDepth});
  cloud->rgba.clear();
  cloud->label.clear();
  surface->assign(cloud->xyz.size(), kSurfaceNone);
  std::mt19937 rng(s.seed);
  std::normal_distribution<double> noise(0.0, s.depth_noise_m);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (int v = 0; v < s.height; ++v) {
    for (int u = 0; u < s.width; ++u) {
      const double dx = (u - s.cx) / s.fx, dy = (v - s.cy) / s.fy;
      // World direction of the ray whose camera z component is 1: t is then the depth.
      double dir[3];
      for (int k = 0; k < 3; ++k) dir[k] = f.x[k] * dx + f.y[k] * dy + f.z[k];
      double best = kInf;
      int32_t id = kSurfaceNone;
      if (dir[2] < 0) {
        const double t = -f.origin[2] / dir[2];
        if (t > 0 && t < best) {
          best = t;
          id = kSurfaceTable;
        }
      }
      if (s.wall_distance_m > 0 && dir[1] > 0) {
        const double t = (s.wall_distance_m - f.origin[1]) / dir[1];
        if (t > 0 && t < best) {
          best = t;
          id = kSurfaceWall;
        }
      }
      for (size_t b = 0; b < s.boxes.size(); ++b) {
        double t0 = 0, t1 = kInf;
        bool hit = true;
        for (int k = 0; k < 3 && hit; ++k) {
          if (std::fabs(dir[k]) < 1e-12) {
            hit = f.origin[k] >= s.boxes[b].min[k] && f.origin[k] <= s.boxes[b].max[k];
            continue;
          }
          double a = (s.boxes[b].min[k] - f.origin[k]) / dir[k];
          double c = (s.boxes[b].max[k] - f.origin[k]) / dir[k];
          if (a > c) std::swap(a, c);
          t0 = std::max(t0, a);
          t1 = std::min(t1, c);
          hit = t0 <= t1;
        }
        if (hit && t0 > 0 && t0 < best) {
          best = t0;
          id = kSurfaceBox0 + static_cast<int32_t>(b);
        }
      }
      if (id == kSurfaceNone) continue;
      const double z = best + noise(rng);
      const size_t idx = static_cast<size_t>(v) * s.width + u;
      cloud->xyz[idx] = core::Vec3f{static_cast<float>(dx * z), static_cast<float>(dy * z),
                                    static_cast<float>(z)};
      (*surface)[idx] = id;
    }
  }
}

void BuildCsr(int num_nodes, const std::vector<std::pair<uint32_t, uint32_t>>& edges,
              std::vector<uint32_t>* offsets, std::vector<uint32_t>* adjacency) {
  std::vector<std::vector<uint32_t>> lists(num_nodes);
  for (const auto& [a, b] : edges) {
    lists[a].push_back(b);
    lists[b].push_back(a);
  }
  offsets->assign(1, 0);
  adjacency->clear();
  for (auto& l : lists) {
    std::sort(l.begin(), l.end());
    l.erase(std::unique(l.begin(), l.end()), l.end());
    adjacency->insert(adjacency->end(), l.begin(), l.end());
    offsets->push_back(static_cast<uint32_t>(adjacency->size()));
  }
}

supervoxel::Supervoxels TileSupervoxels(const core::PointCloud& cloud, int tile,
                                        bool eight_connected) {
  supervoxel::Supervoxels sv;
  sv.width = cloud.width;
  sv.height = cloud.height;
  sv.pixel_label.assign(cloud.xyz.size(), -1);
  const int tw = (cloud.width + tile - 1) / tile;
  const int th = (cloud.height + tile - 1) / tile;
  std::vector<int32_t> tile_id(static_cast<size_t>(tw) * th, -1);
  std::vector<uint32_t> count(tile_id.size(), 0);
  for (int v = 0; v < cloud.height; ++v) {
    for (int u = 0; u < cloud.width; ++u) {
      if (core::IsValid(cloud.xyz[static_cast<size_t>(v) * cloud.width + u])) {
        ++count[static_cast<size_t>(v / tile) * tw + u / tile];
      }
    }
  }
  int32_t next = 0;
  for (size_t t = 0; t < tile_id.size(); ++t) {
    if (count[t] > 0) tile_id[t] = next++;
  }
  for (int v = 0; v < cloud.height; ++v) {
    for (int u = 0; u < cloud.width; ++u) {
      const size_t idx = static_cast<size_t>(v) * cloud.width + u;
      if (core::IsValid(cloud.xyz[idx])) {
        sv.pixel_label[idx] = tile_id[static_cast<size_t>(v / tile) * tw + u / tile];
      }
    }
  }
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  for (int ty = 0; ty < th; ++ty) {
    for (int tx = 0; tx < tw; ++tx) {
      const int32_t a = tile_id[static_cast<size_t>(ty) * tw + tx];
      if (a < 0) continue;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0) continue;
          if (!eight_connected && dx != 0 && dy != 0) continue;
          const int nx = tx + dx, ny = ty + dy;
          if (nx < 0 || ny < 0 || nx >= tw || ny >= th) continue;
          const int32_t b = tile_id[static_cast<size_t>(ny) * tw + nx];
          if (b > a) edges.emplace_back(a, b);
        }
      }
    }
  }
  BuildCsr(next, edges, &sv.adjacency_offsets, &sv.adjacency);
  sv.centroid.assign(next, core::Vec3f{});
  sv.normal.assign(next, core::Vec3f{});
  sv.curvature.assign(next, 0.f);
  sv.num_points.assign(next, 0);
  for (int32_t id : sv.pixel_label) {
    if (id >= 0) ++sv.num_points[id];
  }
  return sv;
}

supervoxel::Supervoxels VoxelSupervoxels(const TabletopScene& scene, const core::PointCloud& cloud,
                                         double cell_m, double z_offset_m) {
  const Frame f = CameraFrame(scene);
  supervoxel::Supervoxels sv;
  sv.width = cloud.width;
  sv.height = cloud.height;
  sv.pixel_label.assign(cloud.xyz.size(), -1);
  std::map<std::tuple<int64_t, int64_t, int64_t>, int32_t> cell_id;
  std::vector<std::array<int64_t, 3>> keys;
  for (size_t p = 0; p < cloud.xyz.size(); ++p) {
    const core::Vec3f& c = cloud.xyz[p];
    if (!core::IsValid(c)) continue;
    int64_t key[3];
    for (int k = 0; k < 3; ++k) {
      const double w =
          f.origin[k] + f.x[k] * c.x + f.y[k] * c.y + f.z[k] * c.z - (k == 2 ? z_offset_m : 0.0);
      key[k] = static_cast<int64_t>(std::floor(w / cell_m + 0.5));
    }
    const auto [it, inserted] = cell_id.try_emplace(std::make_tuple(key[0], key[1], key[2]),
                                                    static_cast<int32_t>(cell_id.size()));
    if (inserted) keys.push_back({key[0], key[1], key[2]});
    sv.pixel_label[p] = it->second;
  }
  const int n = static_cast<int>(cell_id.size());
  // Cells seen side by side in the image are adjacent only when they touch in 3-D (the
  // 26-neighbourhood), as in a voxel adjacency: no edges across depth discontinuities.
  auto touching = [&](int32_t a, int32_t b) {
    for (int k = 0; k < 3; ++k) {
      if (std::abs(keys[a][k] - keys[b][k]) > 1) return false;
    }
    return true;
  };
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  for (int v = 0; v < cloud.height; ++v) {
    for (int u = 0; u < cloud.width; ++u) {
      const int32_t a = sv.pixel_label[static_cast<size_t>(v) * cloud.width + u];
      if (a < 0) continue;
      if (u + 1 < cloud.width) {
        const int32_t b = sv.pixel_label[static_cast<size_t>(v) * cloud.width + u + 1];
        if (b >= 0 && b != a && touching(a, b)) edges.emplace_back(std::min(a, b), std::max(a, b));
      }
      if (v + 1 < cloud.height) {
        const int32_t b = sv.pixel_label[static_cast<size_t>(v + 1) * cloud.width + u];
        if (b >= 0 && b != a && touching(a, b)) edges.emplace_back(std::min(a, b), std::max(a, b));
      }
    }
  }
  BuildCsr(n, edges, &sv.adjacency_offsets, &sv.adjacency);
  sv.centroid.assign(n, core::Vec3f{});
  sv.normal.assign(n, core::Vec3f{});
  sv.curvature.assign(n, 0.f);
  sv.num_points.assign(n, 0);
  for (int32_t id : sv.pixel_label) {
    if (id >= 0) ++sv.num_points[id];
  }
  return sv;
}

std::vector<int32_t> MajoritySurface(const supervoxel::Supervoxels& sv,
                                     const std::vector<int32_t>& surface, double fraction) {
  std::vector<std::map<int32_t, uint32_t>> counts(sv.size());
  for (size_t p = 0; p < sv.pixel_label.size(); ++p) {
    if (sv.pixel_label[p] >= 0) ++counts[sv.pixel_label[p]][surface[p]];
  }
  std::vector<int32_t> out(sv.size(), -2);
  for (size_t i = 0; i < sv.size(); ++i) {
    uint32_t total = 0;
    for (const auto& [id, c] : counts[i]) total += c;
    for (const auto& [id, c] : counts[i]) {
      if (c >= fraction * total) out[i] = id;
    }
  }
  return out;
}

std::vector<int32_t> PureSurfaceOfTiles(const supervoxel::Supervoxels& sv,
                                        const std::vector<int32_t>& surface) {
  std::vector<int32_t> pure(sv.size(), -3);  // -3: not seen yet
  for (size_t p = 0; p < sv.pixel_label.size(); ++p) {
    const int32_t id = sv.pixel_label[p];
    if (id < 0) continue;
    if (pure[id] == -3) {
      pure[id] = surface[p];
    } else if (pure[id] != surface[p]) {
      pure[id] = -2;
    }
  }
  return pure;
}

}  // namespace clutterseg::graph::testing
