#include "clutterseg/core/param_check.h"

#include <charconv>
#include <stdexcept>

namespace clutterseg::core {

namespace {

// The shortest text that reads back to `value` as its own type.
template <typename T>
std::string ShortestText(T value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), value);
  return std::string(buf, ec == std::errc() ? ptr : buf);
}

}  // namespace

std::string FormatParamValue(double value) { return ShortestText(value); }

std::string FormatParamValue(float value) { return ShortestText(value); }

std::string FormatParamValue(int64_t value) { return std::to_string(value); }

std::string ParamCheck::Key(std::string_view field) const {
  if (section_.empty()) return std::string(field);
  return section_ + "." + std::string(field);
}

void ParamCheck::Fail(std::string_view field, std::string_view value,
                      std::string_view expected) const {
  std::string message = Key(field);
  message += " = ";
  message.append(value.empty() ? std::string_view("''") : value);
  message += " is invalid: expected ";
  message.append(expected);
  throw std::invalid_argument(message);
}

void ParamCheck::FailRange(std::string_view field, const std::string& value, const std::string& lo,
                           const std::string& hi, std::string_view unit) const {
  std::string expected = lo;
  expected += "..";
  expected += hi;
  if (!unit.empty()) expected.append(" ").append(unit);
  Fail(field, value, expected);
}

void ParamCheck::FailBound(std::string_view field, const std::string& value,
                           std::string_view relation, const std::string& bound,
                           std::string_view unit) const {
  std::string expected(relation);
  expected += bound;
  if (!unit.empty()) expected.append(" ").append(unit);
  Fail(field, value, expected);
}

void ParamCheck::NonEmpty(std::string_view field, const std::string& value,
                          std::string_view what) const {
  if (value.empty()) Fail(field, "''", what);
}

}  // namespace clutterseg::core
