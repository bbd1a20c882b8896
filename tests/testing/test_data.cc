#include "tests/testing/test_data.h"

#include <cstdlib>

namespace clutterseg::testing {

std::filesystem::path DataDir() {
  if (const char* env = std::getenv("CLUTTERSEG_DATA"); env != nullptr && *env != '\0') {
    return std::filesystem::path(env);
  }
  return std::filesystem::path(CLUTTERSEG_DATA_DIR);
}

bool HaveData(const std::string& relative) {
  std::error_code ec;
  return std::filesystem::exists(DataDir() / relative, ec);
}

std::filesystem::path ScratchDir(const std::string& name) {
  std::filesystem::path dir = std::filesystem::path(CLUTTERSEG_BINARY_DIR) / "test_scratch" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace clutterseg::testing
