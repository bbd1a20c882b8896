#pragma once

#include <string>
#include <vector>

#include "clutterseg/config/key_table.h"
#include "clutterseg/daemon/capture.h"
#include "clutterseg/daemon/heap.h"
#include "clutterseg/daemon/lcm_publisher.h"
#include "clutterseg/daemon/log.h"
#include "clutterseg/daemon/overlay_writer.h"
#include "clutterseg/daemon/realtime.h"
#include "clutterseg/daemon/source_params.h"
#include "clutterseg/daemon/status_reporter.h"
#include "clutterseg/pipeline/frame_runner.h"
#include "clutterseg/pipeline/segmenter_params.h"
#include "clutterseg/pipeline/tracker.h"

namespace clutterseg::daemon {

using config::ConfigError;

/// Everything the `clutterseg` daemon reads from its YAML file (config/clutterseg.yaml
/// documents every key with its default) and command line. Each part of the daemon keeps its
/// parameters in its own struct, here side by side; keys are written as dotted paths, e.g.
/// `lcm.url` or `segmenter.supervoxel.voxel_resolution_m` (ConfigKeys() lists them all).
struct DaemonConfig {
  /// Frame source (key `source`): `device` (first OpenNI2 device), `device:URI`, `FILE.oni`,
  /// a directory of PCD or depth PNG frames, or `synthetic`.
  std::string source{"device"};
  SourceParams camera;                     ///< camera.*: device, depth scale, intrinsics
  CaptureParams capture;                   ///< speed, loop, camera_name, queue, reconnect
  pipeline::FrameRunnerParams processing;  ///< processing.threads, processing.pipeline_depth
  HeapParams heap;                         ///< processing.prefault_heap_mb
  RealtimeParams realtime;                 ///< processing.realtime_priority
  LcmPublisherParams lcm;                  ///< lcm.*
  StatusReporterParams status;             ///< status.*
  OverlayWriterParams overlay;             ///< output.*
  LogLevel log_level{LogLevel::kInfo};     ///< log.level
  pipeline::SegmenterParams segmenter;     ///< the `segmenter:` section
  bool track_objects{true};                ///< tracker.enabled: give objects identities
  pipeline::TrackerParams tracker;         ///< the `tracker:` section

  /// @throws std::invalid_argument naming the key and value of the first bad field
  /// (including the segmenter and tracker parameters), in core::ParamCheck's format.
  void ValidateOrThrow() const;
};

/// Reads and validates a YAML config file; keys absent from the file keep their value in
/// `base` (the built-in defaults unless the caller changed some, e.g. `clutterseg --default`).
/// @throws ConfigError naming `path`, the line, the key path and the value on any problem
/// (also: not a regular file, larger than 1 MiB, a duplicate key, a second document).
DaemonConfig LoadConfig(const std::string& path, DaemonConfig base = {});

/// Parses YAML text (an empty document gives the defaults) and validates the result.
/// `origin` names the text in error messages (usually the file name).
/// @throws ConfigError.
DaemonConfig ParseConfig(const std::string& yaml_text, const std::string& origin);

/// Applies one override "key.path=value" (as given to `--set`) to `config`, parsing the
/// value with the key's type. Does not validate the whole config: call ValidateOrThrow()
/// after the last override. @throws ConfigError naming the key and value.
void ApplyOverride(const std::string& assignment, DaemonConfig* config);

/// Applies `value` to the key `key` (same rules as ApplyOverride).
void SetKey(const std::string& key, const std::string& value, DaemonConfig* config);

/// The value of a key formatted as in YAML. @throws ConfigError for an unknown key.
std::string GetKey(const std::string& key, const DaemonConfig& config);

/// Every accepted key path, in documentation order.
std::vector<std::string> ConfigKeys();

/// The complete configuration as YAML (every key, nested sections), e.g. for
/// `clutterseg --print-config`.
std::string ConfigToYaml(const DaemonConfig& config);

}  // namespace clutterseg::daemon
