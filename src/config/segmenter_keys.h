#pragma once

#include <vector>

#include "clutterseg/config/key_table.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::config {

/// The keys of the `segmenter:` section, relative to it (e.g. "supervoxel.voxel_resolution_m"),
/// mirroring pipeline::SegmenterParams field by field. Defined in segmenter_keys.cc: a new
/// parameter is one line there.
const std::vector<internal::Key<pipeline::SegmenterParams>>& SegmenterKeys();

}  // namespace clutterseg::config
