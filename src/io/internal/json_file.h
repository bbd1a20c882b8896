#pragma once

// The strict JSON file reading shared by io's JSON readers (intrinsics, extrinsics): nlohmann's
// parser with a size limit, duplicate keys and deep nesting refused, errors naming the file
// and the line and column. Private to io.

#include <initializer_list>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace clutterseg::io::internal {

/// Largest JSON file read (bytes).
inline constexpr size_t kMaxJsonBytes = 1u << 20;

/// Parses `text`, the contents of `path`, as one JSON document (RFC 8259, UTF-8). A duplicate
/// key in an object is refused (nlohmann would keep the last one silently) and so is nesting
/// deeper than 64 levels. @throws std::runtime_error "<path>: malformed JSON: line L,
/// column C: ...".
nlohmann::json ParseJsonFile(const std::string& path, const std::string& text);

/// Reads `path` (at most kMaxJsonBytes, not empty) and parses it with ParseJsonFile; `what`
/// names the kind of file in the size message ("an intrinsics file").
/// @throws std::runtime_error naming the file.
nlohmann::json ReadJsonFile(const std::string& path, const std::string& what);

/// The first of `keys` present in `obj`, which must be a number; nullopt when none is present.
/// @throws std::runtime_error naming the file and the key when it is not a number.
std::optional<double> FindNumber(const std::string& path, const nlohmann::json& obj,
                                 std::initializer_list<const char*> keys);

}  // namespace clutterseg::io::internal
