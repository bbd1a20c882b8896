#pragma once

#include <string>
#include <vector>

#include "clutterseg/config/key_table.h"
#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::config {

/// The keys of the `segmenter:` section, relative to it (e.g. "supervoxel.voxel_resolution_m"),
/// mirroring pipeline::SegmenterParams field by field (the voxel grid's fields are written in
/// the supervoxel section). Defined in segmenter_keys.cc: a new parameter is one line there.
const std::vector<Key<pipeline::SegmenterParams>>& SegmenterKeys();

/// The same keys under "segmenter." (as in a configuration file), for tools that read only
/// that section of it.
const KeyTable<pipeline::SegmenterParams>& SegmenterKeyTable();

/// Reads the `segmenter:` section of a configuration file (other sections are ignored, not
/// checked) over `params`. @throws ConfigError naming the file, line, key and value.
void LoadSegmenterParams(const std::string& path, pipeline::SegmenterParams* params);

/// Applies "key=value" for a segmenter key, written with or without the "segmenter." prefix
/// (`supervoxel.seed_resolution_m=0.02`). @throws ConfigError.
void ApplySegmenterOverride(const std::string& assignment, pipeline::SegmenterParams* params);

}  // namespace clutterseg::config
