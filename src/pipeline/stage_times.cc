#include "clutterseg/pipeline/stage_times.h"

namespace clutterseg::pipeline {

const std::array<StageInfo, kNumStages>& StageTable() {
  static const std::array<StageInfo, kNumStages> kTable = {{
      {"points", "depth range (or back-projection) into the working cloud"},
      {"support", "large planes on the pixel grid (support first)"},
      {"voxelize", "voxel octree leaves and 26-adjacency"},
      {"normals", "voxel normals"},
      {"seeding", "supervoxel seeds"},
      {"growth", "supervoxel growth, refinement, connectivity"},
      {"sv_stats", "supervoxel statistics and graph"},
      {"features", "patch eigen-features"},
      {"linkage", "local area linkage and convexity"},
      {"planes", "plane hypotheses"},
      {"expansion", "alpha-expansion"},
      {"refine", "refinement and label image"},
      {"objects", "object statistics"},
  }};
  return kTable;
}

std::string_view StageName(Stage stage) { return StageTable()[static_cast<size_t>(stage)].name; }

double StageTimes::supervoxels_ms() const {
  double sum = 0.0;
  for (Stage s : {Stage::kVoxelize, Stage::kNormals, Stage::kSeeding, Stage::kGrowth,
                  Stage::kSupervoxelStats}) {
    sum += (*this)[s];
  }
  return sum;
}

}  // namespace clutterseg::pipeline
