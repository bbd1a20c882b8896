#pragma once

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace clutterseg::config::internal {

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

/// A key bound to a field of Root.
template <typename Root, typename T>
Key<Root> MakeKey(std::string path, T Root::*field) {
  return {std::move(path),
          [field](const std::string& s, Root* r) { r->*field = Codec<T>::Parse(s); },
          [field](const Root& r) { return Codec<T>::Format(r.*field); }};
}

/// A key bound to a field of a member struct of Root.
template <typename Root, typename Sub, typename T>
Key<Root> MakeKey(std::string path, Sub Root::*sub, T Sub::*field) {
  return {std::move(path),
          [sub, field](const std::string& s, Root* r) { (r->*sub).*field = Codec<T>::Parse(s); },
          [sub, field](const Root& r) { return Codec<T>::Format((r.*sub).*field); }};
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

}  // namespace clutterseg::config::internal
