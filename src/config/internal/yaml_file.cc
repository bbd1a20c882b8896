#include "clutterseg/config/internal/yaml_file.h"

#include <cmath>

#include "clutterseg/config/key_table.h"

namespace clutterseg::config::internal {

void FailYamlFile(const std::string& path, const std::string& kind, const std::string& what) {
  throw ConfigError(path + ": " + kind + ": " + what);
}

YAML::Node LoadYamlDocument(const std::string& text, int* second_line) {
  YAML::Node doc = YAML::Load(text);
  *second_line = SecondYamlDocumentLine(text);
  return doc;
}

YAML::Node LoadYamlFile(const std::string& path, const std::string& kind) {
  const std::string text = ReadConfigFile(path);
  YAML::Node doc;
  int second = 0;
  try {
    doc = LoadYamlDocument(text, &second);
  } catch (const YAML::Exception& e) {
    FailYamlFile(path, kind, "line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (second > 0) {
    FailYamlFile(path, kind,
                 "line " + std::to_string(second) + ": a second YAML document; " +
                     (kind.find_first_of("aeiou") == 0 ? "an " : "a ") + kind + " file holds one");
  }
  return doc;
}

double YamlNumber(const std::string& path, const std::string& kind, const YAML::Node& node,
                  const std::string& field) {
  if (!node || !node.IsScalar()) {
    FailYamlFile(path, kind, "'" + field + "' is missing or not a number");
  }
  double v = 0.0;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    FailYamlFile(path, kind, "'" + field + "' = '" + node.Scalar() + "' is not a number");
  }
  if (!std::isfinite(v)) {
    FailYamlFile(path, kind, "'" + field + "' = " + node.Scalar() + " is not finite");
  }
  return v;
}

}  // namespace clutterseg::config::internal
