#include "clutterseg/core/text_and_color.h"

#include <algorithm>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::core {
namespace {

TEST(NaturalLess, OrdersNumbersByValue) {
  std::vector<std::string> names = {"learn10.pcd", "learn2.pcd",   "learn1.pcd", "learn02.pcd",
                                    "a.pcd",       "learn100.pcd", "learn2b.pcd"};
  std::sort(names.begin(), names.end(),
            [](const std::string& a, const std::string& b) { return NaturalLess(a, b); });
  // Equal numbers: the one written with fewer digits first, whatever follows.
  const std::vector<std::string> expected = {"a.pcd",       "learn1.pcd",  "learn2.pcd",
                                             "learn2b.pcd", "learn02.pcd", "learn10.pcd",
                                             "learn100.pcd"};
  EXPECT_EQ(names, expected);
  EXPECT_FALSE(NaturalLess("x7", "x7"));  // irreflexive
  EXPECT_TRUE(NaturalLess("frame_9", "frame_10"));
  EXPECT_FALSE(NaturalLess("frame_10", "frame_9"));
}

TEST(HsvToRgb, PrimaryAndGreyColours) {
  const Rgb8 red = HsvToRgb(0.0, 1.0, 1.0);
  EXPECT_EQ(red.r, 255);
  EXPECT_EQ(red.g, 0);
  EXPECT_EQ(red.b, 0);
  const Rgb8 green = HsvToRgb(1.0 / 3.0, 1.0, 1.0);
  EXPECT_EQ(green.g, 255);
  EXPECT_EQ(green.r, 0);
  const Rgb8 blue = HsvToRgb(2.0 / 3.0 + 1.0, 1.0, 1.0);  // hue wraps
  EXPECT_EQ(blue.b, 255);
  EXPECT_EQ(blue.g, 0);
  const Rgb8 grey = HsvToRgb(0.4, 0.0, 0.5);
  EXPECT_EQ(grey.r, 128);
  EXPECT_EQ(grey.g, 128);
  EXPECT_EQ(grey.b, 128);
}

}  // namespace
}  // namespace clutterseg::core
