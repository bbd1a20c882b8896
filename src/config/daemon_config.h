#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "clutterseg/pipeline/segmenter_params.h"

namespace clutterseg::config {

/// How a recording is replayed.
enum class Speed {
  kRealtime,  ///< at the recorded frame rate; late frames are dropped like a live camera's
  kMax,       ///< as fast as processing allows, in lockstep: no frame is dropped
};

/// Verbosity of the daemon's stderr log.
enum class LogLevel { kDebug, kInfo, kWarn, kError };

/// Encoding of label_image_t payloads.
enum class LabelCompression { kNone, kRle, kZlib };

/// Everything the `clutterseg` daemon reads from its YAML file (see config/clutterseg.yaml,
/// which documents every key with its default) and command line. Keys are written as dotted
/// paths, e.g. `lcm.url` or `segmenter.supervoxel.voxel_resolution_m`.
struct DaemonConfig {
  /// Frame source: `device` (first OpenNI2 device), `device:URI`, `FILE.oni`, a directory of
  /// PCD or depth PNG frames, or `synthetic`.
  std::string source{"device"};
  Speed speed{Speed::kRealtime};      ///< replay speed of recordings (ignored for live devices)
  bool loop{false};                   ///< restart a recording at its end instead of exiting
  std::string camera_name{"camera"};  ///< camera frame name put in every message

  std::string lcm_url{"udpm://239.255.76.67:7667?ttl=0"};  ///< LCM provider URL
  std::string objects_channel{"CLUTTERSEG_OBJECTS"};       ///< objects_t channel
  std::string labels_channel{"CLUTTERSEG_LABELS"};         ///< label_image_t channel
  std::string status_channel{"CLUTTERSEG_STATUS"};         ///< status_t channel
  bool publish_labels{true};                               ///< publish a label_image_t per frame
  LabelCompression label_compression{LabelCompression::kRle};

  int queue_capacity{2};        ///< frames waiting between capture and processing (drop-oldest)
  int threads{0};               ///< worker threads for segmentation; 0 = number of cores
  int pipeline_depth{2};        ///< frames segmented concurrently (one Segmenter each)
  int64_t max_frames{0};        ///< stop after publishing this many frames; 0 = no limit
  double status_period_s{1.0};  ///< status_t and stderr status line period, seconds
  double reconnect_backoff_min_s{0.5};  ///< first retry delay after device loss, seconds
  double reconnect_backoff_max_s{8.0};  ///< retry delays double up to this, seconds
  LogLevel log_level{LogLevel::kInfo};
  std::string png_dir;  ///< when non-empty, write a label overlay PNG per frame here

  pipeline::SegmenterParams segmenter;  ///< the `segmenter:` section

  /// @throws std::invalid_argument naming the key and value of the first bad field
  /// (including the segmenter parameters).
  void ValidateOrThrow() const;
};

/// A configuration problem (unknown key, wrong type, value out of range, unreadable or
/// malformed file). The message names the file (or "command line"), the key and the value.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Reads and validates a YAML config file; keys absent from the file keep their defaults.
/// @throws ConfigError naming `path`, the key path and the value on any problem.
DaemonConfig LoadConfig(const std::string& path);

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

const char* ToString(Speed speed);
const char* ToString(LogLevel level);
const char* ToString(LabelCompression compression);

}  // namespace clutterseg::config
