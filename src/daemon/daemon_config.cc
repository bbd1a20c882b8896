#include "clutterseg/daemon/daemon_config.h"

#include <stdexcept>
#include <utility>
#include <vector>

#include "clutterseg/config/segmenter_keys.h"
#include "clutterseg/core/param_check.h"

// Codecs of the daemon's enum keys: each written as one of its names.
namespace clutterseg::config {
namespace {

template <typename E>
E ParseName(const std::string& s, const std::vector<std::pair<const char*, E>>& names) {
  std::string choices;
  for (const auto& [name, value] : names) {
    if (s == name) return value;
    if (!choices.empty()) choices.push_back('|');
    choices.append(name);
  }
  throw std::invalid_argument("expected one of " + choices);
}

}  // namespace

template <>
struct Codec<daemon::Speed> {
  static daemon::Speed Parse(const std::string& s) {
    return ParseName<daemon::Speed>(
        s, {{"realtime", daemon::Speed::kRealtime}, {"max", daemon::Speed::kMax}});
  }
  static std::string Format(daemon::Speed v) { return daemon::ToString(v); }
};
template <>
struct Codec<daemon::LabelCompression> {
  static daemon::LabelCompression Parse(const std::string& s) {
    using daemon::LabelCompression;
    return ParseName<LabelCompression>(s, {{"none", LabelCompression::kNone},
                                           {"rle", LabelCompression::kRle},
                                           {"zlib", LabelCompression::kZlib}});
  }
  static std::string Format(daemon::LabelCompression v) { return daemon::ToString(v); }
};
template <>
struct Codec<daemon::LogLevel> {
  static daemon::LogLevel Parse(const std::string& s) {
    using daemon::LogLevel;
    return ParseName<LogLevel>(s, {{"debug", LogLevel::kDebug},
                                   {"info", LogLevel::kInfo},
                                   {"warn", LogLevel::kWarn},
                                   {"error", LogLevel::kError}});
  }
  static std::string Format(daemon::LogLevel v) { return daemon::ToString(v); }
};

}  // namespace clutterseg::config

namespace clutterseg::daemon {
namespace {

using config::Key;
using config::MakeKey;

// The daemon's keys, in documentation order (config/clutterseg.yaml follows it).
const config::KeyTable<DaemonConfig>& DaemonKeys() {
  static const config::KeyTable<DaemonConfig> kKeys = [] {
    using C = DaemonConfig;
    using config::MakeAccessKey;
    std::vector<Key<C>> k = {
        MakeKey("source", &C::source),
        MakeAccessKey<C>(
            "speed", [](auto& c) -> auto& { return c.capture.speed; }),
        MakeKey("loop", &C::capture, &CaptureParams::loop),
        MakeKey("camera_name", &C::capture, &CaptureParams::camera_name),
        MakeKey("camera.serial", &C::camera, &SourceParams::serial),
        MakeKey("camera.width", &C::camera, &SourceParams::width),
        MakeKey("camera.height", &C::camera, &SourceParams::height),
        MakeKey("camera.fps", &C::camera, &SourceParams::fps),
        MakeKey("camera.color", &C::camera, &SourceParams::color),
        MakeKey("camera.registration", &C::camera, &SourceParams::registration),
        MakeKey("camera.intrinsics_file", &C::camera, &SourceParams::intrinsics_file),
        MakeKey("camera.depth_scale_mm", &C::camera, &SourceParams::depth_scale_mm),
        MakeKey("camera.extrinsics_file", &C::camera, &SourceParams::extrinsics_file),
        MakeKey("camera.decimation", &C::camera, &SourceParams::decimation),
        MakeKey("lcm.url", &C::lcm, &LcmPublisherParams::url),
        MakeKey("lcm.objects_channel", &C::lcm, &LcmPublisherParams::objects_channel),
        MakeKey("lcm.labels_channel", &C::lcm, &LcmPublisherParams::labels_channel),
        MakeKey("lcm.status_channel", &C::lcm, &LcmPublisherParams::status_channel),
        MakeKey("lcm.publish_labels", &C::lcm, &LcmPublisherParams::publish_labels),
        MakeAccessKey<C>(
            "lcm.label_compression", [](auto& c) -> auto& { return c.lcm.label_compression; }),
        MakeKey("lcm.queue_capacity", &C::lcm, &LcmPublisherParams::queue_capacity),
        MakeKey("lcm.publish_depth", &C::lcm, &LcmPublisherParams::publish_depth),
        MakeKey("lcm.depth_channel", &C::lcm, &LcmPublisherParams::depth_channel),
        MakeKey("lcm.object_points", &C::lcm, &LcmPublisherParams::object_points),
        MakeKey("lcm.check_instances", &C::lcm, &LcmPublisherParams::check_instances),
        MakeKey("lcm.lock_dir", &C::lcm, &LcmPublisherParams::lock_dir),
        MakeKey("processing.queue_capacity", &C::capture, &CaptureParams::queue_capacity),
        MakeKey("processing.threads", &C::processing, &pipeline::FrameRunnerParams::threads),
        MakeKey("processing.pipeline_depth", &C::processing,
                &pipeline::FrameRunnerParams::pipeline_depth),
        MakeKey("processing.max_frames", &C::capture, &CaptureParams::max_frames),
        MakeKey("processing.prefault_heap_mb", &C::heap, &HeapParams::prefault_mb),
        MakeKey("processing.realtime_priority", &C::realtime, &RealtimeParams::priority),
        MakeKey("status.period_s", &C::status, &StatusReporterParams::period_s),
        MakeKey("reconnect.backoff_min_s", &C::capture, &CaptureParams::reconnect_backoff_min_s),
        MakeKey("reconnect.backoff_max_s", &C::capture, &CaptureParams::reconnect_backoff_max_s),
        MakeAccessKey<C>(
            "log.level", [](auto& c) -> auto& { return c.log_level; }),
        MakeKey("output.png_dir", &C::overlay, &OverlayWriterParams::png_dir),
        MakeKey("output.queue_capacity", &C::overlay, &OverlayWriterParams::queue_capacity),
    };
    config::AppendNested("segmenter", &C::segmenter, config::SegmenterKeys(), &k);
    k.push_back(MakeKey("tracker.enabled", &C::track_objects));
    using T = pipeline::TrackerParams;
    for (auto key :
         {MakeKey("tracker.confirm_frames", &C::tracker, &T::confirm_frames),
          MakeKey("tracker.memory_frames", &C::tracker, &T::memory_frames),
          MakeKey("tracker.tentative_memory_frames", &C::tracker, &T::tentative_memory_frames),
          MakeKey("tracker.hidden_memory_frames", &C::tracker, &T::hidden_memory_frames),
          MakeKey("tracker.newcomer_merge", &C::tracker, &T::newcomer_merge),
          MakeKey("tracker.tentative_merge_memory", &C::tracker, &T::tentative_merge_memory),
          MakeKey("tracker.occluder_is_not_continuation", &C::tracker,
                  &T::occluder_is_not_continuation),
          MakeKey("tracker.merged_memory", &C::tracker, &T::merged_memory),
          MakeKey("tracker.uncovered_view_not_reference", &C::tracker,
                  &T::uncovered_view_not_reference),
          MakeKey("tracker.min_mask_overlap", &C::tracker, &T::min_mask_overlap),
          MakeKey("tracker.max_centroid_step_m", &C::tracker, &T::max_centroid_step_m),
          MakeKey("tracker.max_size_ratio", &C::tracker, &T::max_size_ratio),
          MakeKey("tracker.reacquire_distance_m", &C::tracker, &T::reacquire_distance_m),
          MakeKey("tracker.reacquire_min_box_inside", &C::tracker, &T::reacquire_min_box_inside),
          MakeKey("tracker.reference_decay", &C::tracker, &T::reference_decay),
          MakeKey("tracker.part_min_fraction", &C::tracker, &T::part_min_fraction),
          MakeKey("tracker.split_own_margin_m", &C::tracker, &T::split_own_margin_m),
          MakeKey("tracker.joined_view_frames", &C::tracker, &T::joined_view_frames),
          MakeKey("tracker.continuation_before_reacquire", &C::tracker,
                  &T::continuation_before_reacquire),
          MakeKey("tracker.mask_weight", &C::tracker, &T::mask_weight),
          MakeKey("tracker.lost_score_factor", &C::tracker, &T::lost_score_factor),
          MakeKey("tracker.surface_change_min_step_m", &C::tracker, &T::surface_change_min_step_m),
          MakeKey("tracker.surface_change_min_share", &C::tracker, &T::surface_change_min_share)}) {
      k.push_back(std::move(key));
    }
    return config::KeyTable<DaemonConfig>(std::move(k));
  }();
  return kKeys;
}

// Validates, naming `origin` (the file or "command line") in the message.
void ValidateOrThrowConfig(const DaemonConfig& config, const std::string& origin) {
  try {
    config.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(origin + ": " + e.what());
  }
}

}  // namespace

void DaemonConfig::ValidateOrThrow() const {
  core::ParamCheck("").NonEmpty("source", source, "device, device:URI, FILE.oni, DIR or synthetic");
  camera.ValidateOrThrow();
  capture.ValidateOrThrow();
  processing.ValidateOrThrow();
  heap.ValidateOrThrow();
  realtime.ValidateOrThrow();
  lcm.ValidateOrThrow();
  status.ValidateOrThrow();
  overlay.ValidateOrThrow();
  segmenter.ValidateOrThrow();
  tracker.ValidateOrThrow();
}

DaemonConfig ParseConfig(const std::string& yaml_text, const std::string& origin) {
  DaemonConfig config;
  DaemonKeys().ParseYaml(yaml_text, origin, &config);
  ValidateOrThrowConfig(config, origin);
  return config;
}

DaemonConfig LoadConfig(const std::string& path, DaemonConfig base) {
  DaemonConfig config = std::move(base);
  DaemonKeys().LoadYaml(path, &config);
  ValidateOrThrowConfig(config, path);
  return config;
}

void SetKey(const std::string& key, const std::string& value, DaemonConfig* config) {
  DaemonKeys().Set(key, value, "command line", config);
}

void ApplyOverride(const std::string& assignment, DaemonConfig* config) {
  DaemonKeys().ApplyOverride(assignment, config);
}

std::string GetKey(const std::string& key, const DaemonConfig& config) {
  return DaemonKeys().Get(key, config);
}

std::vector<std::string> ConfigKeys() { return DaemonKeys().paths(); }

std::string ConfigToYaml(const DaemonConfig& config) { return DaemonKeys().ToYaml(config); }

}  // namespace clutterseg::daemon
