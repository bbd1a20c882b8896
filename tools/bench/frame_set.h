#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "clutterseg/core/camera_intrinsics.h"
#include "clutterseg/core/point_cloud.h"

// Input frames of the benchmarks: a directory of PCDs or synthetic renders.
namespace clutterseg::bench {

/// Frames held in memory, with their names and the camera they come from.
struct FrameSet {
  std::string source;  ///< directory or "synthetic(seed=S)"
  std::vector<std::string> names;
  std::vector<core::PointCloud> clouds;
  core::CameraIntrinsics intrinsics;

  size_t size() const { return clouds.size(); }
  /// Heap bytes held by the clouds' buffers (capacities).
  size_t HeapBytes() const;
};

/// Loads every *.pcd of `dir` in natural order (learn2 before learn10), at most `max_frames`
/// (0 = all). Labels are dropped. Intrinsics are the Kinect defaults (fx = fy = 525).
/// @throws std::runtime_error naming the directory or file when nothing can be read.
FrameSet LoadPcdDirectory(const std::string& dir, size_t max_frames);

/// Renders `count` synthetic tabletop scenes with the default scene and sensor parameters at
/// 640x480; frame s uses the seeds of `clutterseg-synth --seed seed` scene s, so the frames
/// equal that tool's output. `threads` render threads (0 = all cores).
FrameSet RenderSyntheticFrames(int count, uint64_t seed, int threads);

/// The same frames as unorganized clouds: the valid points of frame s (with their colour) in
/// a random order (std::mt19937_64 seeded with seed + s) as one row, HEIGHT 1, as an
/// unorganized PCD holds them. The segmenter then finds neighbourhoods without the image grid.
FrameSet ShuffledUnorganized(const FrameSet& frames, uint64_t seed);

}  // namespace clutterseg::bench
