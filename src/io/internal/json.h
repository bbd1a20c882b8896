#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace clutterseg::io::internal {

/// A parsed JSON value. Objects keep their keys in file order (`keys[i]` names `values[i]`).
struct JsonValue {
  enum class Type { kNull, kBool, kNumber, kString, kArray, kObject };

  Type type{Type::kNull};
  bool boolean{false};
  double number{0.0};
  std::string string;
  std::vector<JsonValue> values;  ///< array elements or object members
  std::vector<std::string> keys;  ///< object keys, parallel to `values`

  bool is_object() const { return type == Type::kObject; }
  bool is_array() const { return type == Type::kArray; }
  bool is_number() const { return type == Type::kNumber; }
  /// The member named `key` of an object, or nullptr (also for non-objects). O(members).
  const JsonValue* Find(std::string_view key) const;
};

/// Parses a complete JSON document (RFC 8259; nesting limited to 64 levels; duplicate object
/// keys rejected). Thread-safe.
/// @throws std::runtime_error "line L, column C: <what is wrong>" on malformed input.
JsonValue ParseJson(std::string_view text);

}  // namespace clutterseg::io::internal
