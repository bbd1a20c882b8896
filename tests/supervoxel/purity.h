#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "clutterseg/supervoxel/supervoxels.h"

namespace clutterseg::supervoxel {

/// Points of one supervoxel: all of them, and those of its most common ground-truth region.
struct Purity {
  size_t total{0};
  size_t majority{0};
};

/// Per supervoxel, from `region_of(i)` (the ground-truth region of point i) over the labelled
/// points.
template <typename RegionOf>
std::vector<Purity> SupervoxelPurity(const Supervoxels& sv, RegionOf region_of) {
  std::vector<std::unordered_map<int64_t, size_t>> hist(sv.size());
  for (size_t i = 0; i < sv.pixel_label.size(); ++i) {
    if (sv.pixel_label[i] >= 0) ++hist[static_cast<size_t>(sv.pixel_label[i])][region_of(i)];
  }
  std::vector<Purity> out(sv.size());
  for (size_t s = 0; s < sv.size(); ++s) {
    for (const auto& [region, count] : hist[s]) {
      out[s].total += count;
      out[s].majority = std::max(out[s].majority, count);
    }
  }
  return out;
}

}  // namespace clutterseg::supervoxel
