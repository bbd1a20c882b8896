#include "clutterseg/io/extrinsics_json.h"

#include <stdexcept>
#include <string>

#include "clutterseg/io/internal/json_file.h"

namespace clutterseg::io {
namespace {

using Json = nlohmann::json;

[[noreturn]] void Fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": extrinsics: " + what);
}

// obj[key] as `n` numbers.
void ReadNumbers(const std::string& path, const Json& obj, const char* key, int n, double* out) {
  const auto it = obj.find(key);
  if (it == obj.end()) Fail(path, std::string("missing key '") + key + "'");
  if (!it->is_array() || it->size() != static_cast<size_t>(n)) {
    Fail(path, std::string("'") + key + "' must be an array of " + std::to_string(n) + " numbers");
  }
  for (int i = 0; i < n; ++i) {
    const Json& v = (*it)[static_cast<size_t>(i)];
    if (!v.is_number()) {
      Fail(path, std::string("'") + key + "'[" + std::to_string(i) + "] is not a number");
    }
    out[i] = v.get<double>();
  }
}

std::string ReadString(const std::string& path, const Json& obj, const char* key, bool required) {
  const auto it = obj.find(key);
  if (it == obj.end()) {
    if (required) Fail(path, std::string("missing key '") + key + "'");
    return "";
  }
  if (!it->is_string()) Fail(path, std::string("'") + key + "' is not a string");
  return it->get<std::string>();
}

}  // namespace

core::Extrinsics ReadExtrinsicsJson(const std::string& path) {
  const Json doc = internal::ReadJsonFile(path, "an extrinsics file");
  if (!doc.is_object()) Fail(path, "top level is not a JSON object");
  core::Extrinsics e;
  e.parent_frame = ReadString(path, doc, "parent_frame", true);
  e.child_frame = ReadString(path, doc, "child_frame", false);
  ReadNumbers(path, doc, "translation", 3, e.translation_m);
  ReadNumbers(path, doc, "rotation_xyzw", 4, e.rotation_xyzw);
  if (const std::string problem = e.Problem("'translation'", "'rotation_xyzw'", "'parent_frame'");
      !problem.empty()) {
    Fail(path, problem);
  }
  e.Normalize();
  return e;
}

}  // namespace clutterseg::io
