// The real-data lookup that every `realdata` test goes through: the search order, skipping
// without data, failing with an incomplete set, and refusing a suite that escapes the label.

#include "tests/testing/test_data.h"

#include <cstdlib>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace clutterseg::testing {
namespace {

// Sets CLUTTERSEG_DATA for one test (each ctest test is its own process).
class DataEnv : public ::testing::Test {
 protected:
  void TearDown() override { unsetenv("CLUTTERSEG_DATA"); }
};

TEST_F(DataEnv, NoDataSkipsNamingTheFetchScript) {
  const std::string none = (ScratchDir("data_env_none") / "absent").string();
  setenv("CLUTTERSEG_DATA", none.c_str(), 1);
  EXPECT_FALSE(HaveDataRoot());
  EXPECT_EQ(DataDir(), std::filesystem::path(none));
  bool skip = false;
  const std::string why = CheckRealData("mosd-learn/learn0.pcd", "PcdReaderRealData", &skip);
  EXPECT_TRUE(skip);
  EXPECT_NE(why.find("tools/fetch_data.sh"), std::string::npos) << why;
}

TEST_F(DataEnv, AnIncompleteSetFailsNamingTheFile) {
  const auto root = ScratchDir("data_env_partial");
  std::filesystem::create_directories(root / "mosd-learn");
  std::ofstream(root / "mosd-learn" / "learn1.pcd") << "x";
  setenv("CLUTTERSEG_DATA", root.c_str(), 1);
  EXPECT_TRUE(HaveDataRoot());
  EXPECT_EQ(DataDir(), root);
  bool skip = true;
  EXPECT_EQ(CheckRealData("mosd-learn/learn1.pcd", "PcdReaderRealData", &skip), "");
  const std::string why = CheckRealData("mosd-learn/learn0.pcd", "PcdReaderRealData", &skip);
  EXPECT_FALSE(skip);
  EXPECT_NE(why.find("mosd-learn/learn0.pcd"), std::string::npos) << why;
  EXPECT_NE(why.find("incomplete"), std::string::npos) << why;
}

TEST_F(DataEnv, ASuiteWithoutRealDataInItsNameIsRefused) {
  const auto root = ScratchDir("data_env_suite");
  std::ofstream(root / "f.pcd") << "x";
  setenv("CLUTTERSEG_DATA", root.c_str(), 1);
  bool skip = true;
  const std::string why = CheckRealData("f.pcd", "PcdReaderTest", &skip);
  EXPECT_FALSE(skip);
  EXPECT_NE(why.find("RealData"), std::string::npos) << why;
  EXPECT_EQ(CheckRealData("f.pcd", "Learn/MosdRealDataFrames", &skip), "");
}

}  // namespace
}  // namespace clutterseg::testing
