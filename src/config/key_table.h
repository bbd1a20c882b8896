#pragma once

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace clutterseg::config {

/// A configuration problem (unknown or duplicate key, wrong type, value out of range, a file
/// that cannot be read or is not a YAML map). The message names the file (or "command
/// line"), the line, the key and the value.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Strict scalar codecs shared by the YAML reader and command-line overrides. Parse throws
/// std::invalid_argument("expected ...") when the whole text is not a valid value.
bool ParseBool(const std::string& text);
int ParseInt(const std::string& text);
int64_t ParseInt64(const std::string& text);
float ParseFloat(const std::string& text);
double ParseDouble(const std::string& text);
std::string FormatBool(bool value);
std::string FormatFloat(float value);
std::string FormatDouble(double value);
/// Quotes a string for YAML when needed.
std::string FormatString(const std::string& value);

template <typename T>
struct Codec;
template <>
struct Codec<bool> {
  static bool Parse(const std::string& s) { return ParseBool(s); }
  static std::string Format(bool v) { return FormatBool(v); }
};
template <>
struct Codec<int> {
  static int Parse(const std::string& s) { return ParseInt(s); }
  static std::string Format(int v) { return std::to_string(v); }
};
template <>
struct Codec<int64_t> {
  static int64_t Parse(const std::string& s) { return ParseInt64(s); }
  static std::string Format(int64_t v) { return std::to_string(v); }
};
template <>
struct Codec<float> {
  static float Parse(const std::string& s) { return ParseFloat(s); }
  static std::string Format(float v) { return FormatFloat(v); }
};
template <>
struct Codec<double> {
  static double Parse(const std::string& s) { return ParseDouble(s); }
  static std::string Format(double v) { return FormatDouble(v); }
};
template <>
struct Codec<std::string> {
  static std::string Parse(const std::string& s) { return s; }
  static std::string Format(const std::string& v) { return FormatString(v); }
};

/// One configuration key of a struct `Root`: its dotted path, a setter that parses text and
/// a getter that formats the current value.
template <typename Root>
struct Key {
  std::string path;
  std::function<void(const std::string& text, Root* root)> set;
  std::function<std::string(const Root& root)> get;
};

/// A key bound to the field that `access(root)` returns a reference to, e.g.
/// `[](auto& r) -> auto& { return r.supervoxel.grid.voxel_resolution_m; }` (a generic lambda,
/// so that it serves both the setter and the const getter).
template <typename Root, typename Access>
Key<Root> MakeAccessKey(std::string path, Access access) {
  using T = std::remove_cv_t<std::remove_reference_t<decltype(access(std::declval<Root&>()))>>;
  return {std::move(path),
          [access](const std::string& s, Root* r) { access(*r) = Codec<T>::Parse(s); },
          [access](const Root& r) { return Codec<T>::Format(access(r)); }};
}

/// A key bound to a field of Root.
template <typename Root, typename T>
Key<Root> MakeKey(std::string path, T Root::*field) {
  return MakeAccessKey<Root>(
      std::move(path), [field](auto& r) -> auto& { return r.*field; });
}

/// A key bound to a field of a member struct of Root.
template <typename Root, typename Sub, typename T>
Key<Root> MakeKey(std::string path, Sub Root::*sub, T Sub::*field) {
  return MakeAccessKey<Root>(
      std::move(path), [ sub, field ](auto& r) -> auto& { return (r.*sub).*field; });
}

/// A key bound to an enum field, written as one of `names`.
template <typename Root, typename E>
Key<Root> MakeEnumKey(std::string path, E Root::*field,
                      std::vector<std::pair<std::string, E>> names) {
  auto set = [field, names](const std::string& s, Root* r) {
    std::string choices;
    for (const auto& [name, value] : names) {
      if (name == s) {
        r->*field = value;
        return;
      }
      choices += (choices.empty() ? "" : "|") + name;
    }
    throw std::invalid_argument("expected one of " + choices);
  };
  auto get = [field, names](const Root& r) {
    for (const auto& [name, value] : names) {
      if (value == r.*field) return name;
    }
    return std::string("?");
  };
  return {std::move(path), set, get};
}

/// Re-roots the keys of a sub-struct under `prefix.` in Root.
template <typename Root, typename Sub>
void AppendNested(const std::string& prefix, Sub Root::*sub, const std::vector<Key<Sub>>& keys,
                  std::vector<Key<Root>>* out) {
  for (const Key<Sub>& k : keys) {
    out->push_back({prefix + "." + k.path,
                    [sub, set = k.set](const std::string& s, Root* r) { set(s, &(r->*sub)); },
                    [sub, get = k.get](const Root& r) { return get(r.*sub); }});
  }
}

namespace internal {

/// Reads a configuration file: it must be a regular file (a directory, FIFO or device is an
/// error, never a blocking open) of at most 1 MiB. @throws ConfigError naming `path`.
std::string ReadConfigFile(const std::string& path);

/// The line (1-based) where a second YAML document of `text` starts, or 0 when `text` holds
/// at most one. Documents are pulled one at a time and two at the most: yaml-cpp 0.7's LoadAll
/// never ends on some malformed input (`,"a":1,"b":1e6x":2}` makes it build empty documents
/// until memory runs out), and a file here must hold one document anyway. Thread-safe.
/// @throws YAML::Exception (yaml-cpp's) on a syntax error.
int SecondYamlDocumentLine(const std::string& text);

/// Walks a YAML document (exactly one; a second document, duplicate keys, anchors that
/// redefine a key and non-scalar keys are errors). For every scalar value at a key path in
/// `paths` calls set(index into paths, value text, "origin:line"); a map at a prefix of some
/// path is a section. With a non-empty `only_section`, top-level keys other than it are
/// skipped unread. @throws ConfigError naming origin, line and key (with a suggestion for a
/// mistyped key); errors of `set` (std::invalid_argument) are reported with the value.
void WalkYaml(const std::string& text, const std::string& origin,
              const std::vector<std::string>& paths, const std::string& only_section,
              const std::function<void(size_t, const std::string&)>& set);

/// " (did you mean 'x'?)" or " (keys of 's': ...)" for an unknown `path`, or "".
std::string SuggestKey(const std::string& path, const std::vector<std::string>& paths);

/// Nested YAML for (path, formatted value) pairs in table order.
std::string KeysToYaml(const std::vector<std::pair<std::string, std::string>>& values);

}  // namespace internal

/// The keys of a configuration struct `Root` and the readers over them: YAML files, text and
/// `key=value` overrides. Parsing does not validate Root as a whole: call its
/// ValidateOrThrow() after the last change.
///
/// Thread-safety: immutable after construction; any thread.
template <typename Root>
class KeyTable {
 public:
  explicit KeyTable(std::vector<Key<Root>> keys) : keys_(std::move(keys)) {
    for (const Key<Root>& k : keys_) paths_.push_back(k.path);
  }

  const std::vector<Key<Root>>& keys() const { return keys_; }
  /// Every key path, in table (documentation) order.
  const std::vector<std::string>& paths() const { return paths_; }

  /// Applies the keys of YAML `text` to `root`; `origin` names the text in messages. With
  /// `only_section`, other top-level sections are ignored. @throws ConfigError.
  void ParseYaml(const std::string& text, const std::string& origin, Root* root,
                 const std::string& only_section = {}) const {
    internal::WalkYaml(text, origin, paths_, only_section,
                       [&](size_t i, const std::string& value) { keys_[i].set(value, root); });
  }
  /// Reads `path` (internal::ReadConfigFile) and applies it. @throws ConfigError.
  void LoadYaml(const std::string& path, Root* root, const std::string& only_section = {}) const {
    ParseYaml(internal::ReadConfigFile(path), path, root, only_section);
  }
  /// Sets one key from text. @throws ConfigError naming `origin`, the key and the value.
  void Set(const std::string& key, const std::string& value, const std::string& origin,
           Root* root) const {
    const Key<Root>& k = Find(key, origin);
    try {
      k.set(value, root);
    } catch (const std::invalid_argument& e) {
      throw ConfigError(origin + ": key '" + key + "': " + e.what() + ", got '" + value + "'");
    }
  }
  /// Applies "key.path=value" (as given to --set). @throws ConfigError.
  void ApplyOverride(const std::string& assignment, Root* root) const {
    const size_t eq = assignment.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw ConfigError("command line: expected key=value, got '" + assignment + "'");
    }
    Set(assignment.substr(0, eq), assignment.substr(eq + 1), "command line", root);
  }
  /// The value of `key` formatted as in YAML. @throws ConfigError for an unknown key.
  std::string Get(const std::string& key, const Root& root) const {
    return Find(key, "configuration").get(root);
  }
  /// Every key with its value, as nested YAML.
  std::string ToYaml(const Root& root) const {
    std::vector<std::pair<std::string, std::string>> values;
    for (const Key<Root>& k : keys_) values.emplace_back(k.path, k.get(root));
    return internal::KeysToYaml(values);
  }

 private:
  const Key<Root>& Find(const std::string& key, const std::string& origin) const {
    for (const Key<Root>& k : keys_) {
      if (k.path == key) return k;
    }
    throw ConfigError(origin + ": unknown key '" + key + "'" + internal::SuggestKey(key, paths_));
  }

  std::vector<Key<Root>> keys_;
  std::vector<std::string> paths_;
};

}  // namespace clutterseg::config
