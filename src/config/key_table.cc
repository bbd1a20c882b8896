#include "clutterseg/config/key_table.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <set>
#include <sstream>

#include <sys/stat.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include "clutterseg/config/internal/yaml_file.h"

namespace clutterseg::config {

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

int ParseInt(const std::string& text) { return ParseInteger<int>(text, "an integer"); }
int64_t ParseInt64(const std::string& text) { return ParseInteger<int64_t>(text, "an integer"); }

float ParseFloat(const std::string& text) {
  const double v = ParseReal(text);
  if (std::fabs(v) > 3.4e38) throw std::invalid_argument("expected a finite number (float)");
  return static_cast<float>(v);
}
double ParseDouble(const std::string& text) { return ParseReal(text); }

std::string FormatBool(bool value) { return value ? "true" : "false"; }
std::string FormatFloat(float value) { return FormatReal(value); }
std::string FormatDouble(double value) { return FormatReal(value); }

std::string FormatString(const std::string& value) {
  YAML::Emitter out;
  out << value;
  std::string s = out.c_str();
  return s.empty() ? "\"\"" : s;
}

namespace internal {
namespace {

constexpr off_t kMaxConfigBytes = 1 << 20;

bool IsSection(const std::string& path, const std::vector<std::string>& paths) {
  for (const std::string& k : paths) {
    if (k.size() > path.size() && k.compare(0, path.size(), path) == 0 && k[path.size()] == '.') {
      return true;
    }
  }
  return false;
}

std::string LastComponent(const std::string& path) {
  const size_t dot = path.rfind('.');
  return dot == std::string::npos ? path : path.substr(dot + 1);
}

std::string Where(const std::string& origin, const YAML::Mark& mark) {
  if (mark.line < 0) return origin;
  return origin + ":" + std::to_string(mark.line + 1);
}

struct Walker {
  const std::string& origin;
  const std::vector<std::string>& paths;
  const std::function<void(size_t, const std::string&)>& set;

  void Walk(const YAML::Node& node, const std::string& prefix, const std::string& only) {
    std::set<std::string> seen;  // keys of this map, for duplicates
    for (const auto& item : node) {
      const YAML::Node& key_node = item.first;
      const YAML::Node& value = item.second;
      const std::string where = Where(origin, key_node.Mark());
      if (!key_node.IsScalar()) throw ConfigError(where + ": keys must be plain names");
      const std::string& name = key_node.Scalar();
      const std::string path = prefix.empty() ? name : prefix + "." + name;
      if (!seen.insert(name).second) {
        throw ConfigError(where + ": key '" + path + "' appears twice in the same map");
      }
      if (prefix.empty() && !only.empty() && name != only) continue;
      size_t index = paths.size();
      for (size_t i = 0; i < paths.size(); ++i) {
        if (paths[i] == path) index = i;
      }
      if (index < paths.size()) {
        if (value.IsNull()) {
          throw ConfigError(where + ": key '" + path +
                            "' has no value (write the default to keep it)");
        }
        if (!value.IsScalar()) {
          throw ConfigError(where + ": key '" + path + "': expected a single value, got a " +
                            (value.IsMap() ? "map" : "list"));
        }
        try {
          set(index, value.Scalar());
        } catch (const std::invalid_argument& e) {
          throw ConfigError(Where(origin, value.Mark()) + ": key '" + path + "': " + e.what() +
                            ", got '" + value.Scalar() + "'");
        }
      } else if (IsSection(path, paths)) {
        if (value.IsNull()) continue;  // an empty section keeps the defaults
        if (!value.IsMap()) {
          throw ConfigError(where + ": key '" + path +
                            "' is a section: expected a map of keys, got '" +
                            (value.IsScalar() ? value.Scalar() : std::string("a list")) + "'");
        }
        Walk(value, path, only);
      } else {
        throw ConfigError(where + ": unknown key '" + path + "'" + SuggestKey(path, paths));
      }
    }
  }
};

}  // namespace

std::string ReadConfigFile(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) {
    throw ConfigError(path + ": cannot open config file: " + std::strerror(errno));
  }
  if (S_ISDIR(st.st_mode)) throw ConfigError(path + ": is a directory, not a config file");
  if (!S_ISREG(st.st_mode)) {
    throw ConfigError(path +
                      ": is not a regular file (a FIFO, socket or device); give a YAML file");
  }
  if (st.st_size > kMaxConfigBytes) {
    throw ConfigError(path + ": config file of " + std::to_string(st.st_size) +
                      " bytes is larger than the limit of 1 MiB");
  }
  // O_NONBLOCK: should the path have become a FIFO since stat(), open() does not wait.
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw ConfigError(path + ": cannot open config file: " + std::strerror(errno));
  std::string text;
  char buf[65536];
  for (;;) {
    const ssize_t got = read(fd, buf, sizeof(buf));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) {
      const int err = errno;
      close(fd);
      throw ConfigError(path + ": cannot read config file: " + std::strerror(err));
    }
    if (got == 0) break;
    text.append(buf, static_cast<size_t>(got));
    if (static_cast<off_t>(text.size()) > kMaxConfigBytes) {
      close(fd);
      throw ConfigError(path + ": config file is larger than the limit of 1 MiB");
    }
  }
  close(fd);
  return text;
}

namespace {

// Notes where the second document starts; every other event is ignored.
class DocumentCounter final : public YAML::EventHandler {
 public:
  int documents{0};
  int second_line{0};  // 1-based

  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents == 2) second_line = mark.line + 1;
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

}  // namespace

int SecondYamlDocumentLine(const std::string& text) {
  std::istringstream stream(text);
  YAML::Parser parser(stream);
  DocumentCounter counter;
  for (int i = 0; i < 2 && parser.HandleNextDocument(counter); ++i) {
  }
  return counter.documents >= 2 ? std::max(counter.second_line, 1) : 0;
}

void WalkYaml(const std::string& text, const std::string& origin,
              const std::vector<std::string>& paths, const std::string& only_section,
              const std::function<void(size_t, const std::string&)>& set) {
  YAML::Node doc;
  int second = 0;
  try {
    doc = LoadYamlDocument(text, &second);
  } catch (const YAML::Exception& e) {
    throw ConfigError(Where(origin, e.mark) + ": YAML syntax error: " + e.msg);
  }
  if (second > 0) {
    throw ConfigError(origin + ":" + std::to_string(second) +
                      ": a second YAML document; a config file holds one");
  }
  if (doc.IsNull()) return;
  if (!doc.IsMap()) throw ConfigError(origin + ": expected a map of keys at the top level");
  try {
    Walker{origin, paths, set}.Walk(doc, "", only_section);
  } catch (const YAML::Exception& e) {
    throw ConfigError(Where(origin, e.mark) + ": " + e.msg);
  }
}

std::string SuggestKey(const std::string& path, const std::vector<std::string>& paths) {
  const std::string last = LastComponent(path);
  for (const std::string& k : paths) {
    if (LastComponent(k) == last) return " (did you mean '" + k + "'?)";
  }
  const size_t dot = path.rfind('.');
  const std::string parent = dot == std::string::npos ? "" : path.substr(0, dot);
  if (!parent.empty() && IsSection(parent, paths)) {
    std::string keys;
    for (const std::string& k : paths) {
      if (k.compare(0, parent.size() + 1, parent + ".") == 0 &&
          k.find('.', parent.size() + 1) == std::string::npos) {
        keys += (keys.empty() ? "" : ", ") + k.substr(parent.size() + 1);
      }
    }
    if (!keys.empty()) return " (keys of '" + parent + "': " + keys + ")";
  }
  return "";
}

std::string KeysToYaml(const std::vector<std::pair<std::string, std::string>>& values) {
  // Keys are grouped by section in table order; nested maps with two-space indents.
  std::ostringstream out;
  std::vector<std::string> open;  // currently open sections
  for (const auto& [path, value] : values) {
    std::vector<std::string> parts;
    std::stringstream ss(path);
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
    out << std::string(2 * (parts.size() - 1), ' ') << parts.back() << ": " << value << "\n";
  }
  return out.str();
}

}  // namespace internal
}  // namespace clutterseg::config
