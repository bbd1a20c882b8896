#include "clutterseg/io/internal/json_file.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string_view>
#include <unordered_set>
#include <vector>

#include "clutterseg/core/file_kind.h"

namespace clutterseg::io::internal {
namespace {

using Json = nlohmann::json;

[[noreturn]] void Fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": " + what);
}

// Deepest nesting of arrays and objects a JSON file may have.
constexpr int kMaxJsonDepth = 64;

// nlohmann's message without its "[json.exception.<kind>.<id>] " and "parse error at line L,
// column C: " prefixes (the position is given as ours).
std::string_view JsonReason(const Json::exception& e) {
  std::string_view what = e.what();
  if (const size_t p = what.find("] "); p != std::string_view::npos) what.remove_prefix(p + 2);
  if (what.starts_with("parse error")) {
    if (const size_t p = what.find(": "); p != std::string_view::npos) what.remove_prefix(p + 2);
  }
  return what;
}

// "line L, column C" of the byte nlohmann's parse_error points at (1-based `byte`).
std::string LineAndColumn(const std::string& text, size_t byte) {
  const size_t at = std::min(byte > 0 ? byte - 1 : 0, text.size());
  const size_t line = 1 + static_cast<size_t>(std::count(text.begin(), text.begin() + at, '\n'));
  const size_t newline = at == 0 ? std::string::npos : text.rfind('\n', at - 1);
  const size_t column = at - (newline == std::string::npos ? 0 : newline + 1) + 1;
  return "line " + std::to_string(line) + ", column " + std::to_string(column);
}

}  // namespace

Json ParseJsonFile(const std::string& path, const std::string& text) {
  std::vector<std::unordered_set<std::string>> keys;  // of each open array (unused) and object
  auto check = [&](int depth, Json::parse_event_t event, Json& parsed) {
    if (depth > kMaxJsonDepth) {
      Fail(path,
           "malformed JSON: nesting deeper than " + std::to_string(kMaxJsonDepth) + " levels");
    }
    switch (event) {
      case Json::parse_event_t::object_start:
      case Json::parse_event_t::array_start:
        keys.emplace_back();
        break;
      case Json::parse_event_t::object_end:
      case Json::parse_event_t::array_end:
        keys.pop_back();
        break;
      case Json::parse_event_t::key: {
        const std::string& key = parsed.get_ref<const std::string&>();
        if (!keys.back().insert(key).second) {
          Fail(path, "malformed JSON: duplicate key \"" + key + "\"");
        }
        break;
      }
      case Json::parse_event_t::value:
        break;
    }
    return true;
  };
  try {
    return Json::parse(text, check);
  } catch (const Json::parse_error& e) {
    Fail(path,
         "malformed JSON: " + LineAndColumn(text, e.byte) + ": " + std::string(JsonReason(e)));
  } catch (const Json::out_of_range& e) {  // a number beyond the range of double
    Fail(path, "malformed JSON: number out of range: " + std::string(JsonReason(e)));
  }
}

std::optional<double> FindNumber(const std::string& path, const Json& obj,
                                 std::initializer_list<const char*> keys) {
  for (const char* key : keys) {
    const auto it = obj.find(key);
    if (it == obj.end()) continue;
    if (!it->is_number()) Fail(path, std::string("key '") + key + "' is not a number");
    return it->get<double>();
  }
  return std::nullopt;
}

Json ReadJsonFile(const std::string& path, const std::string& what) {
  // A FIFO would block fopen() until a writer comes: refused before it is opened.
  if (core::IsNonRegularFile(path)) {
    Fail(path, "not a regular file (a FIFO, device or directory); not " + what);
  }
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"),
                                                          &std::fclose);
  if (f == nullptr) Fail(path, std::string("cannot open: ") + std::strerror(errno));
  std::string text;
  char buf[4096];
  size_t got = 0;
  while ((got = std::fread(buf, 1, sizeof buf, f.get())) > 0) {
    text.append(buf, got);
    if (text.size() > kMaxJsonBytes) {
      Fail(path, "larger than " + std::to_string(kMaxJsonBytes) + " bytes; not " + what);
    }
  }
  if (std::ferror(f.get()) != 0) Fail(path, "read error");
  if (text.empty()) Fail(path, "empty file");
  return ParseJsonFile(path, text);
}

}  // namespace clutterseg::io::internal
