#pragma once

#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace clutterseg::core {

/// A small streaming JSON writer for tool outputs (objects, results, manifests). Produces
/// compact, valid JSON; non-finite numbers are written as null. Not thread-safe.
class JsonWriter {
 public:
  JsonWriter& BeginObject() {
    Sep();
    os_ << '{';
    first_.push_back(true);
    return *this;
  }
  JsonWriter& EndObject() {
    os_ << '}';
    first_.pop_back();
    return *this;
  }
  JsonWriter& BeginArray() {
    Sep();
    os_ << '[';
    first_.push_back(true);
    return *this;
  }
  JsonWriter& EndArray() {
    os_ << ']';
    first_.pop_back();
    return *this;
  }
  /// Writes `"name":`; the next value call writes the value.
  JsonWriter& Key(std::string_view name) {
    Sep();
    WriteString(name);
    os_ << ':';
    after_key_ = true;
    return *this;
  }
  JsonWriter& Value(std::string_view s) {
    Sep();
    WriteString(s);
    return *this;
  }
  JsonWriter& Value(const char* s) { return Value(std::string_view(s)); }
  JsonWriter& Value(bool b) {
    Sep();
    os_ << (b ? "true" : "false");
    return *this;
  }
  JsonWriter& Value(double d) {
    Sep();
    if (std::isfinite(d)) {
      os_.precision(9);
      os_ << d;
    } else {
      os_ << "null";
    }
    return *this;
  }
  JsonWriter& Value(float f) { return Value(static_cast<double>(f)); }
  JsonWriter& Value(int64_t i) {
    Sep();
    os_ << i;
    return *this;
  }
  JsonWriter& Value(uint64_t i) {
    Sep();
    os_ << i;
    return *this;
  }
  JsonWriter& Value(int i) { return Value(static_cast<int64_t>(i)); }
  JsonWriter& Value(uint32_t i) { return Value(static_cast<uint64_t>(i)); }
  template <typename T>
  JsonWriter& Field(std::string_view name, const T& v) {
    Key(name);
    return Value(v);
  }
  /// Writes a fixed-size numeric array.
  JsonWriter& Array(std::string_view name, std::initializer_list<double> values) {
    Key(name);
    BeginArray();
    for (double v : values) Value(v);
    return EndArray();
  }
  std::string str() const { return os_.str(); }

 private:
  void Sep() {
    if (after_key_) {
      after_key_ = false;
      return;
    }
    if (!first_.empty()) {
      if (!first_.back()) os_ << ',';
      first_.back() = false;
    }
  }
  void WriteString(std::string_view s) {
    os_ << '"';
    for (char c : s) {
      switch (c) {
        case '"':
          os_ << "\\\"";
          break;
        case '\\':
          os_ << "\\\\";
          break;
        case '\n':
          os_ << "\\n";
          break;
        case '\t':
          os_ << "\\t";
          break;
        case '\r':
          os_ << "\\r";
          break;
        default:
          if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", c);
            os_ << buf;
          } else {
            os_ << c;
          }
      }
    }
    os_ << '"';
  }
  std::ostringstream os_;
  std::vector<bool> first_;
  bool after_key_{false};
};

}  // namespace clutterseg::core
