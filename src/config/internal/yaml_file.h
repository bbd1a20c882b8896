#pragma once

// Reading of the small calibration YAML files (camera_info, extrinsics): one document, its
// numbers finite, every error naming the file, the kind of file and the field. Private to
// config.

#include <string>

#include <yaml-cpp/yaml.h>

namespace clutterseg::config::internal {

/// Reads the one YAML document of `text` (yaml-cpp's Load(), which drops any later document
/// without a word) and sets `*second_line` to SecondYamlDocumentLine(text) (0: none), so that
/// each caller refuses a second document in its own words. Thread-safe.
/// @throws YAML::Exception (yaml-cpp's) on a syntax error.
YAML::Node LoadYamlDocument(const std::string& text, int* second_line);

/// Reads `path` (internal::ReadConfigFile: a regular file of at most 1 MiB) as exactly one
/// YAML document. @throws ConfigError "<path>: <kind>: line L: ..." on a syntax error or a
/// second document.
YAML::Node LoadYamlFile(const std::string& path, const std::string& kind);

/// [[noreturn]] throws ConfigError "<path>: <kind>: <what>".
[[noreturn]] void FailYamlFile(const std::string& path, const std::string& kind,
                               const std::string& what);

/// `node` as a finite number. @throws ConfigError naming the file, `kind` and `field` when it
/// is missing, not a scalar, not a number, NaN or infinite.
double YamlNumber(const std::string& path, const std::string& kind, const YAML::Node& node,
                  const std::string& field);

}  // namespace clutterseg::config::internal
