#include "tests/testing/test_data.h"

#include <unistd.h>

#include <cstdlib>
#include <string>

namespace clutterseg::testing {
namespace {

bool IsDirectory(const std::filesystem::path& p) {
  std::error_code ec;
  return std::filesystem::is_directory(p, ec);
}

// The first existing place of the search order, or "" when none exists.
std::filesystem::path FoundRoot() {
  if (const char* env = std::getenv("CLUTTERSEG_DATA"); env != nullptr && *env != '\0') {
    return IsDirectory(env) ? std::filesystem::path(env) : std::filesystem::path();
  }
  const std::filesystem::path source(CLUTTERSEG_SOURCE_DIR);
  for (const auto& candidate : {source / "data", source / ".." / "shared" / "data"}) {
    if (IsDirectory(candidate)) return candidate;
  }
  return {};
}

}  // namespace

std::filesystem::path DataDir() {
  std::filesystem::path root = FoundRoot();
  if (!root.empty()) return root;
  if (const char* env = std::getenv("CLUTTERSEG_DATA"); env != nullptr && *env != '\0') {
    return std::filesystem::path(env);
  }
  return std::filesystem::path(CLUTTERSEG_SOURCE_DIR) / "data";
}

bool HaveDataRoot() { return !FoundRoot().empty(); }

bool HaveData(const std::string& relative) {
  std::error_code ec;
  return std::filesystem::exists(DataDir() / relative, ec);
}

std::string CheckRealData(const std::string& relative, const std::string& suite, bool* skip) {
  *skip = false;
  if (suite.find("RealData") == std::string::npos) {
    return "test suite '" + suite +
           "' reads real data but its name lacks \"RealData\", so ctest would not label it "
           "realdata (see docs/testing.md)";
  }
  if (!HaveDataRoot()) {
    *skip = true;
    return "real data not found (CLUTTERSEG_DATA, " + DataDir().string() +
           ", ../shared/data): run tools/fetch_data.sh to fetch it";
  }
  if (!HaveData(relative)) {
    return "real data '" + relative + "' missing under " + DataDir().string() +
           ": the set is incomplete; run tools/fetch_data.sh again";
  }
  return {};
}

std::filesystem::path ScratchDir(const std::string& name) {
  // ctest runs the tests of one binary in parallel processes: the process id keeps two tests
  // that use the same name from deleting each other's files.
  std::filesystem::path dir = std::filesystem::path(CLUTTERSEG_BINARY_DIR) / "test_scratch" /
                              (name + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace clutterseg::testing
