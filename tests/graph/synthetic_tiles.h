#pragma once

#include <cstdint>
#include <vector>

#include "clutterseg/core/point_cloud.h"
#include "clutterseg/core/types.h"
#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::graph::testing {

/// An axis-aligned box in the world frame (X right, Y forward, Z up), metres.
struct WorldBox {
  double min[3];
  double max[3];
};

/// A tabletop scene seen by a pinhole camera at height `camera_height_m` above the table
/// plane Z = 0, pitched down by `pitch_deg`, with an optional wall Y = wall_distance_m.
struct TabletopScene {
  int width{640};
  int height{480};
  double fx{525.0}, fy{525.0}, cx{319.5}, cy{239.5};
  double camera_height_m{0.7};
  double pitch_deg{35.0};
  double wall_distance_m{2.0};  ///< <= 0: no wall
  std::vector<WorldBox> boxes;
  double depth_noise_m{0.0005};  ///< Gaussian noise on depth, metres
  uint32_t seed{1};
};

/// Surface ids written per pixel by Render.
inline constexpr int32_t kSurfaceNone = -1;
inline constexpr int32_t kSurfaceTable = 0;
inline constexpr int32_t kSurfaceWall = 1;
inline constexpr int32_t kSurfaceBox0 = 2;  ///< box k is kSurfaceBox0 + k

/// Ray-casts the scene into an organized cloud (camera frame) and a per-pixel surface id.
void Render(const TabletopScene& scene, core::PointCloud* cloud, std::vector<int32_t>* surface);

/// Plane of the table (normal towards the camera, n . p + d = 0) in the camera frame.
void TablePlane(const TabletopScene& scene, core::Vec3f* normal, float* d);
/// Plane of the wall in the camera frame.
void WallPlane(const TabletopScene& scene, core::Vec3f* normal, float* d);

/// Chops an organized cloud into square tiles of `tile` pixels; every tile with at least
/// one valid point becomes a supervoxel (numbered in raster order of tiles), adjacent to the
/// tiles among its 8 (or 4) neighbours. Fills pixel_label, adjacency and num_points; the
/// centroid/normal/curvature fields are left empty-sized-correctly (zeros).
supervoxel::Supervoxels TileSupervoxels(const core::PointCloud& cloud, int tile,
                                        bool eight_connected = true);

/// Groups the points of a rendered `scene` by cubic cells of `cell_m` in the world frame
/// (cell centres on multiples of cell_m, so axis-aligned faces at such coordinates lie mid
/// cell): a stand-in for 3-D supervoxels with roughly isotropic patches. Cells are numbered
/// in raster order of their first pixel; two cells are adjacent when 4-neighbouring pixels
/// carry them and touch in 3-D (26-neighbourhood). `z_offset_m` shifts the cell boundaries
/// along world Z.
supervoxel::Supervoxels VoxelSupervoxels(const TabletopScene& scene, const core::PointCloud& cloud,
                                         double cell_m, double z_offset_m = 0.0);

/// For each supervoxel: the surface id holding at least `fraction` of its pixels, or -2.
std::vector<int32_t> MajoritySurface(const supervoxel::Supervoxels& sv,
                                     const std::vector<int32_t>& surface, double fraction);

/// For each supervoxel: the surface id shared by all its pixels, or -2 when mixed.
std::vector<int32_t> PureSurfaceOfTiles(const supervoxel::Supervoxels& sv,
                                        const std::vector<int32_t>& surface);

/// Builds a symmetric sorted CSR adjacency from an undirected edge list.
void BuildCsr(int num_nodes, const std::vector<std::pair<uint32_t, uint32_t>>& edges,
              std::vector<uint32_t>* offsets, std::vector<uint32_t>* adjacency);

}  // namespace clutterseg::graph::testing
