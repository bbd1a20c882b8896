#pragma once

#include <filesystem>
#include <string>

namespace clutterseg::testing {

/// Directory of the shared real data sets (../shared/data beside the checkout), or the value
/// of the CLUTTERSEG_DATA environment variable when set.
std::filesystem::path DataDir();

/// True when `DataDir()/relative` exists; tests call GTEST_SKIP() with a message otherwise.
bool HaveData(const std::string& relative);

/// A fresh empty directory under the build tree for one test's outputs, private to this
/// process (the name gets the process id appended).
std::filesystem::path ScratchDir(const std::string& name);

}  // namespace clutterseg::testing

/// Skips the current test with a clear message when shared data is missing.
#define CLUTTERSEG_REQUIRE_DATA(rel)                                                \
  do {                                                                              \
    if (!::clutterseg::testing::HaveData(rel)) {                                    \
      GTEST_SKIP() << "shared data '" << (rel) << "' not found under "              \
                   << ::clutterseg::testing::DataDir() << " (set CLUTTERSEG_DATA)"; \
    }                                                                               \
  } while (0)
