#include "tests/testing/test_data.h"

#include <unistd.h>

#include <cstdlib>
#include <string>

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
  // ctest runs the tests of one binary in parallel processes: the process id keeps two tests
  // that use the same name from deleting each other's files.
  std::filesystem::path dir = std::filesystem::path(CLUTTERSEG_BINARY_DIR) / "test_scratch" /
                              (name + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace clutterseg::testing
