#include "clutterseg/io/internal/json.h"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace clutterseg::io {
namespace {

using internal::JsonValue;
using internal::ParseJson;

TEST(JsonTest, ParsesAllValueKinds) {
  const JsonValue v = ParseJson(
      " {\"a\": [1, -2.5e-3, 0, 1E+2], \"b\": {\"c\": null, \"d\": true, \"e\": false},"
      " \"s\": \"q\\\"\\\\\\/\\b\\f\\n\\r\\t\\u0041\\u00e9\\ud83d\\ude00\"}\n");
  ASSERT_TRUE(v.is_object());
  const JsonValue* a = v.Find("a");
  ASSERT_NE(a, nullptr);
  ASSERT_TRUE(a->is_array());
  ASSERT_EQ(a->values.size(), 4u);
  EXPECT_EQ(a->values[0].number, 1.0);
  EXPECT_EQ(a->values[1].number, -2.5e-3);
  EXPECT_EQ(a->values[3].number, 100.0);
  const JsonValue* b = v.Find("b");
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(b->Find("c")->type, JsonValue::Type::kNull);
  EXPECT_TRUE(b->Find("d")->boolean);
  EXPECT_EQ(b->Find("e")->type, JsonValue::Type::kBool);
  EXPECT_FALSE(b->Find("e")->boolean);
  EXPECT_EQ(v.Find("s")->string, "q\"\\/\b\f\n\r\tA\xc3\xa9\xf0\x9f\x98\x80");
  EXPECT_EQ(v.Find("missing"), nullptr);
  EXPECT_EQ(a->Find("x"), nullptr);
}

TEST(JsonTest, RejectsMalformedDocuments) {
  for (const char* bad : {"",        "{",           "{\"a\" 1}",   "{\"a\": 1,}",
                          "[1 2]",   "[01]",        "[1.]",        "[.5]",
                          "[1e]",    "[-]",         "\"abc",       "\"a\tb\"",
                          "\"\\x\"", "\"\\ud800\"", "\"\\udc00\"", "\"\\u12g4\"",
                          "tru",     "nul",         "{} {}",       "{\"a\":1,\"a\":2}",
                          "[1e400]", "{1: 2}"}) {
    EXPECT_THROW(ParseJson(bad), std::runtime_error) << bad;
  }
}

TEST(JsonTest, ErrorsGiveLineAndColumn) {
  try {
    ParseJson("{\n  \"a\": [1,\n  ]\n}");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("line 3, column 3:", 0), 0u) << e.what();
  }
}

TEST(JsonTest, LimitsNesting) {
  EXPECT_NO_THROW(ParseJson(std::string(60, '[') + std::string(60, ']')));
  EXPECT_THROW(ParseJson(std::string(100000, '[')), std::runtime_error);
}

}  // namespace
}  // namespace clutterseg::io
