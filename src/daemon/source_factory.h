#pragma once

#include <memory>
#include <string>

#include "clutterseg/core/frame_source.h"
#include "clutterseg/daemon/daemon_config.h"

namespace clutterseg::daemon {

/// What a `source` string names.
enum class SourceKind { kDevice, kOniFile, kPcdDirectory, kDepthPngDirectory, kSynthetic };

/// Classifies `source`: "device" or "device:URI", "synthetic", a path ending in ".oni", or an
/// existing directory (PCD files -> kPcdDirectory, otherwise depth PNGs).
/// @throws SourceOpenError naming the value when it names no existing file or directory
/// (or a file that is not an .oni recording).
SourceKind ClassifySource(const std::string& source);

/// Whether `source` names one stream of frames of a scene: a camera, an .oni recording or the
/// synthetic source, whose frames the temporal depth filter (`segmenter.temporal`) averages.
/// False for a directory of files (PCD, depth PNG), whose frames need not show one scene, and
/// for a name that classifies as nothing. Never throws.
bool IsFrameStream(const std::string& source);

/// Builds (does not open) the frame source named by `config.source`, configured from
/// `config` (speed, loop, camera name). @throws SourceOpenError when the path does not
/// exist, std::invalid_argument when the source kind is not built into this binary or its
/// options are invalid.
std::unique_ptr<core::FrameSource> MakeSource(const DaemonConfig& config);

/// Process-wide set-up some sources need before other threads start (OpenNI2 changes the
/// working directory while it initializes). Call once from main() when `config.source` is a
/// device or an .oni file. @throws std::runtime_error when the driver cannot initialize.
void InitializeSourceDrivers(const DaemonConfig& config);
/// Counterpart of InitializeSourceDrivers, after every source is closed.
void ShutdownSourceDrivers();

}  // namespace clutterseg::daemon
