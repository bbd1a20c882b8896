#include "clutterseg/config/daemon_config.h"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "clutterseg/config/key_table.h"
#include "clutterseg/config/segmenter_keys.h"

namespace clutterseg::config {
namespace internal {

bool ParseBool(const std::string& text) {
  std::string s;
  for (char c : text) s += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (s == "true" || s == "yes" || s == "on") return true;
  if (s == "false" || s == "no" || s == "off") return false;
  throw std::invalid_argument("expected a boolean (true or false)");
}

namespace {
template <typename T>
T ParseInteger(const std::string& text, const char* what) {
  T value{};
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  if (begin != end && *begin == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec == std::errc::result_out_of_range)
    throw std::invalid_argument(std::string("expected ") + what + " (out of range)");
  if (ec != std::errc() || ptr != end || begin == end)
    throw std::invalid_argument(std::string("expected ") + what);
  return value;
}

double ParseReal(const std::string& text) {
  if (text.empty()) throw std::invalid_argument("expected a number");
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v)) {
    throw std::invalid_argument("expected a finite number");
  }
  return v;
}
}  // namespace

int ParseInt(const std::string& text) { return ParseInteger<int>(text, "an integer"); }
int64_t ParseInt64(const std::string& text) { return ParseInteger<int64_t>(text, "an integer"); }

float ParseFloat(const std::string& text) {
  const double v = ParseReal(text);
  if (std::fabs(v) > 3.4e38) throw std::invalid_argument("expected a finite number (float)");
  return static_cast<float>(v);
}
double ParseDouble(const std::string& text) { return ParseReal(text); }

std::string FormatBool(bool value) { return value ? "true" : "false"; }

namespace {
template <typename T>
std::string FormatReal(T value) {
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), value);
  std::string s(buf, ec == std::errc() ? ptr : buf);
  // Keep a decimal point so YAML readers see a float.
  if (s.find_first_of(".eE") == std::string::npos && s.find_first_of("ni") == std::string::npos) {
    s += ".0";
  }
  return s;
}
}  // namespace

std::string FormatFloat(float value) { return FormatReal(value); }
std::string FormatDouble(double value) { return FormatReal(value); }

std::string FormatString(const std::string& value) {
  YAML::Emitter out;
  out << value;
  std::string s = out.c_str();
  return s.empty() ? "\"\"" : s;
}

}  // namespace internal

namespace {

using internal::Key;
using internal::MakeEnumKey;
using internal::MakeKey;

// The daemon's keys, in documentation order (config/clutterseg.yaml follows it).
const std::vector<Key<DaemonConfig>>& DaemonKeys() {
  static const std::vector<Key<DaemonConfig>> kKeys = [] {
    using C = DaemonConfig;
    std::vector<Key<C>> k = {
        MakeKey("source", &C::source),
        MakeEnumKey("speed", &C::speed, {{"realtime", Speed::kRealtime}, {"max", Speed::kMax}}),
        MakeKey("loop", &C::loop),
        MakeKey("camera_name", &C::camera_name),
        MakeKey("lcm.url", &C::lcm_url),
        MakeKey("lcm.objects_channel", &C::objects_channel),
        MakeKey("lcm.labels_channel", &C::labels_channel),
        MakeKey("lcm.status_channel", &C::status_channel),
        MakeKey("lcm.publish_labels", &C::publish_labels),
        MakeEnumKey("lcm.label_compression", &C::label_compression,
                    {{"none", LabelCompression::kNone},
                     {"rle", LabelCompression::kRle},
                     {"zlib", LabelCompression::kZlib}}),
        MakeKey("processing.queue_capacity", &C::queue_capacity),
        MakeKey("processing.threads", &C::threads),
        MakeKey("processing.pipeline_depth", &C::pipeline_depth),
        MakeKey("processing.max_frames", &C::max_frames),
        MakeKey("status.period_s", &C::status_period_s),
        MakeKey("reconnect.backoff_min_s", &C::reconnect_backoff_min_s),
        MakeKey("reconnect.backoff_max_s", &C::reconnect_backoff_max_s),
        MakeEnumKey("log.level", &C::log_level,
                    {{"debug", LogLevel::kDebug},
                     {"info", LogLevel::kInfo},
                     {"warn", LogLevel::kWarn},
                     {"error", LogLevel::kError}}),
        MakeKey("output.png_dir", &C::png_dir),
    };
    internal::AppendNested("segmenter", &C::segmenter, SegmenterKeys(), &k);
    return k;
  }();
  return kKeys;
}

const Key<DaemonConfig>* FindKey(const std::string& path) {
  for (const auto& k : DaemonKeys()) {
    if (k.path == path) return &k;
  }
  return nullptr;
}

bool IsSection(const std::string& path) {
  for (const auto& k : DaemonKeys()) {
    if (k.path.size() > path.size() && k.path.compare(0, path.size(), path) == 0 &&
        k.path[path.size()] == '.') {
      return true;
    }
  }
  return false;
}

std::string LastComponent(const std::string& path) {
  const size_t dot = path.rfind('.');
  return dot == std::string::npos ? path : path.substr(dot + 1);
}

// A hint for a mistyped key: keys sharing the last component or the longest prefix.
std::string Suggest(const std::string& path) {
  const std::string last = LastComponent(path);
  for (const auto& k : DaemonKeys()) {
    if (LastComponent(k.path) == last) return " (did you mean '" + k.path + "'?)";
  }
  const std::string parent =
      path.substr(0, path.rfind('.') == std::string::npos ? 0 : path.rfind('.'));
  if (!parent.empty() && IsSection(parent)) {
    std::string keys;
    for (const auto& k : DaemonKeys()) {
      if (k.path.compare(0, parent.size() + 1, parent + ".") == 0 &&
          k.path.find('.', parent.size() + 1) == std::string::npos) {
        keys += (keys.empty() ? "" : ", ") + k.path.substr(parent.size() + 1);
      }
    }
    if (!keys.empty()) return " (keys of '" + parent + "': " + keys + ")";
  }
  return "";
}

std::string Where(const std::string& origin, const YAML::Mark& mark) {
  if (mark.line < 0) return origin;
  return origin + ":" + std::to_string(mark.line + 1);
}

void SetFromText(const Key<DaemonConfig>& key, const std::string& text, const std::string& where,
                 DaemonConfig* config) {
  try {
    key.set(text, config);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(where + ": key '" + key.path + "': " + e.what() + ", got '" + text + "'");
  }
}

void Walk(const YAML::Node& node, const std::string& prefix, const std::string& origin,
          DaemonConfig* config) {
  for (const auto& item : node) {
    const YAML::Node& key_node = item.first;
    const YAML::Node& value = item.second;
    const std::string where = Where(origin, key_node.Mark());
    if (!key_node.IsScalar()) throw ConfigError(where + ": keys must be plain names");
    const std::string path = prefix.empty() ? key_node.Scalar() : prefix + "." + key_node.Scalar();
    if (const Key<DaemonConfig>* key = FindKey(path)) {
      if (value.IsNull()) {
        throw ConfigError(where + ": key '" + path +
                          "' has no value (write the default to keep it)");
      }
      if (!value.IsScalar()) {
        throw ConfigError(where + ": key '" + path + "': expected a single value, got a " +
                          (value.IsMap() ? "map" : "list"));
      }
      SetFromText(*key, value.Scalar(), Where(origin, value.Mark()), config);
    } else if (IsSection(path)) {
      if (value.IsNull()) continue;  // an empty section keeps the defaults
      if (!value.IsMap()) {
        throw ConfigError(where + ": key '" + path +
                          "' is a section: expected a map of keys, got '" +
                          (value.IsScalar() ? value.Scalar() : std::string("a list")) + "'");
      }
      Walk(value, path, origin, config);
    } else {
      throw ConfigError(where + ": unknown key '" + path + "'" + Suggest(path));
    }
  }
}

void ValidateOrThrowConfig(const DaemonConfig& config, const std::string& origin) {
  try {
    config.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(origin + ": " + e.what());
  }
}

}  // namespace

void DaemonConfig::ValidateOrThrow() const {
  auto fail = [](const std::string& key, const std::string& value, const char* want) {
    throw std::invalid_argument("key '" + key + "' = " + value + " is invalid (" + want + ")");
  };
  if (source.empty())
    fail("source", "''", "expected device, device:URI, FILE.oni, DIR or synthetic");
  if (lcm_url.empty()) fail("lcm.url", "''", "expected an LCM URL such as memq:// or udpm://...");
  if (objects_channel.empty()) fail("lcm.objects_channel", "''", "expected a channel name");
  if (labels_channel.empty()) fail("lcm.labels_channel", "''", "expected a channel name");
  if (status_channel.empty()) fail("lcm.status_channel", "''", "expected a channel name");
  if (camera_name.empty()) fail("camera_name", "''", "expected a name");
  if (queue_capacity < 1 || queue_capacity > 1024) {
    fail("processing.queue_capacity", std::to_string(queue_capacity), "expected 1..1024");
  }
  if (threads < 0 || threads > 256)
    fail("processing.threads", std::to_string(threads), "expected 0..256, 0 = cores");
  if (pipeline_depth < 1 || pipeline_depth > 8) {
    fail("processing.pipeline_depth", std::to_string(pipeline_depth), "expected 1..8");
  }
  if (max_frames < 0)
    fail("processing.max_frames", std::to_string(max_frames), "expected >= 0, 0 = no limit");
  if (!(status_period_s >= 0.05 && status_period_s <= 3600.0)) {
    fail("status.period_s", internal::FormatDouble(status_period_s), "expected 0.05..3600 s");
  }
  if (!(reconnect_backoff_min_s > 0.0 && reconnect_backoff_min_s <= 3600.0)) {
    fail("reconnect.backoff_min_s", internal::FormatDouble(reconnect_backoff_min_s),
         "expected (0, 3600] s");
  }
  if (!(reconnect_backoff_max_s >= reconnect_backoff_min_s && reconnect_backoff_max_s <= 3600.0)) {
    fail("reconnect.backoff_max_s", internal::FormatDouble(reconnect_backoff_max_s),
         "expected >= reconnect.backoff_min_s and <= 3600 s");
  }
  try {
    segmenter.ValidateOrThrow();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("section 'segmenter': ") + e.what());
  }
}

DaemonConfig ParseConfig(const std::string& yaml_text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(Where(origin, e.mark) + ": YAML syntax error: " + e.msg);
  }
  DaemonConfig config;
  if (root.IsNull()) {
    ValidateOrThrowConfig(config, origin);
    return config;
  }
  if (!root.IsMap()) throw ConfigError(origin + ": expected a map of keys at the top level");
  try {
    Walk(root, "", origin, &config);
  } catch (const YAML::Exception& e) {
    throw ConfigError(Where(origin, e.mark) + ": " + e.msg);
  }
  ValidateOrThrowConfig(config, origin);
  return config;
}

DaemonConfig LoadConfig(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path + ": cannot open config file: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ConfigError(path + ": cannot read config file");
  return ParseConfig(text.str(), path);
}

void SetKey(const std::string& key, const std::string& value, DaemonConfig* config) {
  const Key<DaemonConfig>* k = FindKey(key);
  if (k == nullptr) {
    throw ConfigError("command line: unknown key '" + key + "'" + Suggest(key));
  }
  SetFromText(*k, value, "command line", config);
}

void ApplyOverride(const std::string& assignment, DaemonConfig* config) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ConfigError("command line: expected key=value, got '" + assignment + "'");
  }
  SetKey(assignment.substr(0, eq), assignment.substr(eq + 1), config);
}

std::string GetKey(const std::string& key, const DaemonConfig& config) {
  const Key<DaemonConfig>* k = FindKey(key);
  if (k == nullptr) throw ConfigError("unknown key '" + key + "'");
  return k->get(config);
}

std::vector<std::string> ConfigKeys() {
  std::vector<std::string> keys;
  for (const auto& k : DaemonKeys()) keys.push_back(k.path);
  return keys;
}

std::string ConfigToYaml(const DaemonConfig& config) {
  // Keys are grouped by section in table order; emit nested maps with two-space indents.
  std::ostringstream out;
  std::vector<std::string> open;  // currently open sections
  for (const auto& k : DaemonKeys()) {
    std::vector<std::string> parts;
    std::stringstream ss(k.path);
    for (std::string p; std::getline(ss, p, '.');) parts.push_back(p);
    size_t common = 0;
    while (common < open.size() && common + 1 < parts.size() && open[common] == parts[common]) {
      ++common;
    }
    open.resize(common);
    for (size_t i = common; i + 1 < parts.size(); ++i) {
      out << std::string(2 * i, ' ') << parts[i] << ":\n";
      open.push_back(parts[i]);
    }
    out << std::string(2 * (parts.size() - 1), ' ') << parts.back() << ": " << k.get(config)
        << "\n";
  }
  return out.str();
}

const char* ToString(Speed speed) { return speed == Speed::kMax ? "max" : "realtime"; }

const char* ToString(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "debug";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kWarn:
      return "warn";
    case LogLevel::kError:
      return "error";
  }
  return "info";
}

const char* ToString(LabelCompression compression) {
  switch (compression) {
    case LabelCompression::kNone:
      return "none";
    case LabelCompression::kRle:
      return "rle";
    case LabelCompression::kZlib:
      return "zlib";
  }
  return "zlib";
}

}  // namespace clutterseg::config
