#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>

namespace clutterseg::core {

/// Formats a parameter value for messages: integers as integers, floating-point values in
/// the shortest form that reads back to the same value of their own type (a float 0.004 as
/// "0.004", not as the double it widens to).
std::string FormatParamValue(double value);
std::string FormatParamValue(float value);
std::string FormatParamValue(int64_t value);

/// The one validation helper of every parameter struct (`ValidateOrThrow()`): each check
/// throws std::invalid_argument with one message format that names the configuration key,
///
///     <section>.<field> = <value> is invalid: expected <what>
///
/// e.g. "segmenter.supervoxel.voxel_resolution_m = 2 is invalid: expected 0.0001..1 m".
/// `section` is the dotted path of the struct in the YAML configuration (docs/configuration.md),
/// so the message says which line of the file to change.
///
/// Thread-safety: immutable after construction; any thread.
class ParamCheck {
 public:
  explicit ParamCheck(std::string_view section) : section_(section) {}

  /// The full key of `field`: "<section>.<field>", or `field` when the section is empty.
  std::string Key(std::string_view field) const;

  /// Throws with `expected` (e.g. "0.0001..1 m") for the value text `value`.
  [[noreturn]] void Fail(std::string_view field, std::string_view value,
                         std::string_view expected) const;

  /// Fails unless `ok`; `value` is only formatted then.
  template <typename T>
  void Require(bool ok, std::string_view field, T value, std::string_view expected) const {
    if (!ok) Fail(field, Format(value), expected);
  }

  /// lo <= value <= hi; floating-point values must also be finite. `unit` is appended to the
  /// range in the message ("0.0001..1 m").
  template <typename T>
  void InRange(std::string_view field, T value, T lo, T hi, std::string_view unit = {}) const {
    if (!(Finite(value) && value >= lo && value <= hi)) {
      FailRange(field, Format(value), Format(lo), Format(hi), unit);
    }
  }
  /// value >= lo (and finite).
  template <typename T>
  void AtLeast(std::string_view field, T value, T lo, std::string_view unit = {}) const {
    if (!(Finite(value) && value >= lo)) FailBound(field, Format(value), ">= ", Format(lo), unit);
  }
  /// value > 0 (and finite).
  template <typename T>
  void Positive(std::string_view field, T value, std::string_view unit = {}) const {
    if (!(Finite(value) && value > T{0})) FailBound(field, Format(value), "> ", "0", unit);
  }
  /// A non-empty string; `what` describes what is expected ("a channel name").
  void NonEmpty(std::string_view field, const std::string& value, std::string_view what) const;

 private:
  template <typename T>
  static bool Finite(T value) {
    if constexpr (std::is_floating_point_v<T>) {
      return std::isfinite(value);
    } else {
      return true;
    }
  }
  template <typename T>
  static std::string Format(T value) {
    if constexpr (std::is_same_v<T, bool>) {
      return value ? "true" : "false";
    } else if constexpr (std::is_same_v<T, float>) {
      return FormatParamValue(value);
    } else if constexpr (std::is_floating_point_v<T>) {
      return FormatParamValue(static_cast<double>(value));
    } else if constexpr (std::is_integral_v<T>) {
      return FormatParamValue(static_cast<int64_t>(value));
    } else {
      return std::string(value);
    }
  }
  // Out of line: the messages are built in param_check.cc.
  [[noreturn]] void FailRange(std::string_view field, const std::string& value,
                              const std::string& lo, const std::string& hi,
                              std::string_view unit) const;
  [[noreturn]] void FailBound(std::string_view field, const std::string& value,
                              std::string_view relation, const std::string& bound,
                              std::string_view unit) const;

  std::string section_;
};

}  // namespace clutterseg::core
