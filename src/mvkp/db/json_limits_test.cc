#include "mvkp/db/json_limits.h"

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

std::string Nested(int depth, bool arrays) {
  std::string s;
  for (int i = 0; i < depth; ++i) s += arrays ? "[" : "{\"a\":";
  s += "1";
  for (int i = 0; i < depth; ++i) s += arrays ? "]" : "}";
  return s;
}

TEST(JsonLimits, AcceptsWhatIsWithinTheLimits) {
  const auto j = ParseJsonLimited(R"({"a": [1, 2, {"b": "c"}], "d": null})");
  EXPECT_EQ(j["a"][2]["b"], "c");
  EXPECT_NO_THROW(ParseJsonLimited(Nested(32, true)));
  EXPECT_NO_THROW(ParseJsonLimited(Nested(32, false)));
}

TEST(JsonLimits, RefusesDeepNestingBeforeBuildingIt) {
  // 100 000 levels: parsed without limits this value crashes (stack) when
  // copied, dumped or destroyed recursively.
  for (bool arrays : {true, false}) {
    try {
      ParseJsonLimited(Nested(100000, arrays), {}, "meta");
      FAIL() << "no error";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
      EXPECT_NE(std::string(e.what()).find("meta: nested deeper than 32 levels"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(ParseJsonLimited(Nested(33, true)), Error);
  JsonLimits shallow;
  shallow.max_depth = 2;
  EXPECT_NO_THROW(ParseJsonLimited("[[1]]", shallow));
  EXPECT_THROW(ParseJsonLimited("[[[1]]]", shallow), Error);
}

TEST(JsonLimits, RefusesLongTextsAndStrings) {
  JsonLimits l;
  l.max_bytes = 10;
  EXPECT_THROW(ParseJsonLimited("[1,2,3,4,5,6]", l), Error);
  l = {};
  l.max_string_bytes = 4;
  EXPECT_NO_THROW(ParseJsonLimited(R"({"abcd": "wxyz"})", l));
  EXPECT_THROW(ParseJsonLimited(R"({"abcd": "vwxyz"})", l), Error);
  EXPECT_THROW(ParseJsonLimited(R"({"abcde": 1})", l), Error);
}

TEST(JsonLimits, SyntaxErrorsAreErrorsNamingTheInput) {
  for (const char* bad : {"", "{", "[1,]", "{\"a\" 1}", "nul", "\"\\x\""}) {
    try {
      ParseJsonLimited(bad, {}, "request body");
      FAIL() << bad;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind("request body is not valid JSON: ", 0), 0u) << e.what();
    }
  }
  nlohmann::json out = 5;
  EXPECT_FALSE(TryParseJsonLimited(Nested(1000, true), out));
  EXPECT_TRUE(out.is_null());
  EXPECT_TRUE(TryParseJsonLimited("{}", out));
  EXPECT_TRUE(out.is_object());
}

}  // namespace
}  // namespace mvkp
