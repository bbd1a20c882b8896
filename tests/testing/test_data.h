#pragma once

#include <filesystem>
#include <string>

namespace clutterseg::testing {

/// Root of the real RGB-D data sets (mOSD, PCL scenes, OSD/UCN/TUM PNGs; see
/// docs/testing.md), searched in this order: the CLUTTERSEG_DATA environment variable when set,
/// the checkout's `data/` folder that tools/fetch_data.sh fills, then `../shared/data` beside
/// the checkout. When none exists, the path of `data/` (where the data would go).
std::filesystem::path DataDir();

/// True when one of the places DataDir() searches exists: the real data is expected to be
/// complete there, so a test that then misses a file fails instead of skipping.
bool HaveDataRoot();

/// True when `DataDir()/relative` exists.
bool HaveData(const std::string& relative);

/// What a test of gtest suite `suite` that reads the real data file `relative` does first
/// (CLUTTERSEG_REQUIRE_DATA): "" when it may go on; otherwise the message to skip with (no
/// data root at all) or to fail with (a data root without `relative`, or a suite whose name
/// lacks "RealData" and so escapes the ctest label `realdata`). `*skip` says which.
std::string CheckRealData(const std::string& relative, const std::string& suite, bool* skip);

/// A fresh empty directory under the build tree for one test's outputs, private to this
/// process (the name gets the process id appended).
std::filesystem::path ScratchDir(const std::string& name);

}  // namespace clutterseg::testing

/// First statement of a test that reads the real data file `rel` (relative to DataDir()). The
/// test's suite name must contain "RealData": that is how clutterseg_add_test gives it the
/// ctest label `realdata`. Without any data the test skips, naming tools/fetch_data.sh; with a
/// data root that lacks `rel` it fails.
#define CLUTTERSEG_REQUIRE_DATA(rel)                                                       \
  do {                                                                                     \
    bool clutterseg_skip_ = false;                                                         \
    const std::string clutterseg_why_ = ::clutterseg::testing::CheckRealData(              \
        (rel), ::testing::UnitTest::GetInstance()->current_test_info()->test_suite_name(), \
        &clutterseg_skip_);                                                                \
    if (!clutterseg_why_.empty()) {                                                        \
      if (clutterseg_skip_) GTEST_SKIP() << clutterseg_why_;                               \
      FAIL() << clutterseg_why_;                                                           \
    }                                                                                      \
  } while (0)
