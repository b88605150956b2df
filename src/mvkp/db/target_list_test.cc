#include "mvkp/db/target_list.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;

// Runs fn, expecting mvkp::Error with `code` and a message containing `part`.
void ExpectError(const std::function<void()>& fn, ErrorCode code, const std::string& part) {
  try {
    fn();
    ADD_FAILURE() << "no error; expected one containing \"" << part << "\"";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

std::vector<TargetListEntry> Csv(const std::string& text) { return ParseTargetList(text, TargetListFormat::kCsv, "l.csv"); }
std::vector<TargetListEntry> Json(const std::string& text) {
  return ParseTargetList(text, TargetListFormat::kJson, "l.json");
}
void BadCsv(const std::string& text, const std::string& part) {
  ExpectError([&] { Csv(text); }, ErrorCode::kInvalidArgument, part);
}
void BadJson(const std::string& text, const std::string& part) {
  ExpectError([&] { Json(text); }, ErrorCode::kInvalidArgument, part);
}

std::string Nested(int depth) {
  std::string s;
  for (int i = 0; i < depth; ++i) s += "{\"a\":";
  s += "1";
  for (int i = 0; i < depth; ++i) s += "}";
  return s;
}

// A CSV field holding `text`: quoted, quotes doubled.
std::string CsvField(const std::string& text) {
  std::string f = "\"";
  for (char c : text) f += c == '"' ? std::string("\"\"") : std::string(1, c);
  return f + "\"";
}

TEST(TargetList, CsvColumnsInAnyOrderWithQuotes) {
  const auto l = Csv(
      "\xEF\xBB\xBFimage,id,title,year,meta\r\n"
      "a.jpg,a,\"Mona, Lisa\",1503,\"{\"\"room\"\": 7}\"\r\n"
      "\n"
      "  \r\n"
      "/abs/b.png,b\n");
  ASSERT_EQ(l.size(), 2u);
  EXPECT_EQ(l[0].first.id, "a");
  EXPECT_EQ(l[0].second, "a.jpg");
  EXPECT_EQ(l[0].first.title, "Mona, Lisa");
  EXPECT_EQ(l[0].first.year, "1503");
  EXPECT_EQ(l[0].first.meta, "{\"room\": 7}");
  EXPECT_EQ(l[1].first.id, "b");
  EXPECT_EQ(l[1].second, "/abs/b.png");
  EXPECT_EQ(l[1].first.title, "");
  EXPECT_EQ(l[1].first.meta, "{}");
  EXPECT_TRUE(Csv("id,image\n").empty());
}

TEST(TargetList, CsvErrorsNameTheLine) {
  BadCsv("", "l.csv: empty list");
  BadCsv("id,title\na,b\n", "needs 'id' and 'image' columns");
  BadCsv("id,image\na,a.jpg\n,b.jpg\n", "l.csv:3: needs an id and an image");
  BadCsv("id,image\na,\"a.jpg\n", "l.csv:2: unterminated quoted field");
  BadCsv("id,image,meta\na,a.jpg,[1]\n", "l.csv:2: meta must be a JSON object");
  BadCsv("id,image,meta\na,a.jpg,{\n", "l.csv:2: meta is not valid JSON");
  BadCsv("id,image,meta\na,a.jpg," + CsvField(Nested(100)) + "\n", "l.csv:2: meta: nested deeper than 16 levels");
  BadCsv("id,image,meta\na,a.jpg," + CsvField(Nested(100000)) + "\n", "l.csv:2: meta: 600001 bytes, at most 65536");
  TargetListLimits few;
  few.max_entries = 1;
  ExpectError([&] { ParseTargetList("id,image\na,a\nb,b\n", TargetListFormat::kCsv, "l.csv", few); },
              ErrorCode::kInvalidArgument, "more than 1 targets");
  few = {};
  few.max_bytes = 10;
  ExpectError([&] { ParseTargetList("id,image\na,a\n", TargetListFormat::kCsv, "l.csv", few); },
              ErrorCode::kInvalidArgument, "at most 10");
}

TEST(TargetList, JsonEntries) {
  const auto l = Json(R"([{"id": "a", "image": "a.jpg", "title": "T", "year": 1889, "meta": {"room": [1, 2]}},
                           {"id": "b", "image": "b.jpg", "year": "c. 1500", "url": null, "extra": 5}])");
  ASSERT_EQ(l.size(), 2u);
  EXPECT_EQ(l[0].first.title, "T");
  EXPECT_EQ(l[0].first.year, "1889");
  EXPECT_EQ(l[0].first.meta, R"({"room":[1,2]})");
  EXPECT_EQ(l[1].first.year, "c. 1500");
  EXPECT_EQ(l[1].first.url, "");
  EXPECT_EQ(l[1].first.meta, "{}");
  EXPECT_TRUE(Json("[]").empty());
}

TEST(TargetList, JsonErrorsNameTheEntry) {
  BadJson("{", "l.json is not valid JSON");
  BadJson(R"({"id": "a"})", "expected a JSON array");
  BadJson(R"([{"id": "a", "image": "a.jpg"}, 5])", "entry 2: expected an object");
  BadJson(R"([{"id": "a"}])", "entry 1: needs string 'id' and 'image'");
  BadJson(R"([{"id": 1, "image": "a.jpg"}])", "entry 1: 'id' must be a string");
  BadJson(R"([{"id": "", "image": "a.jpg"}])", "entry 1: needs a non-empty");
  BadJson(R"([{"id": "a", "image": "a.jpg", "title": [1]}])", "entry 1: 'title' must be a string");
  BadJson(R"([{"id": "a", "image": "a.jpg", "meta": "x"}])", "entry 1: meta must be a JSON object");
  BadJson(R"([{"id": "a", "image": "a.jpg", "meta": {"k": ")" + std::string(20000, 'x') + "\"}}]",
          "entry 1: meta: a string longer than");
}

// Issue 19: `db import` of a JSON list whose meta nests 300 000 levels
// crashed (stack overflow); it is refused while parsing.
TEST(TargetList, DeepJsonIsRefusedNotACrash) {
  BadJson(R"([{"id": "a", "image": "a.jpg", "meta": )" + Nested(300000) + "}]", "l.json: nested deeper than 18 levels");
  BadJson(std::string(300000, '[') + std::string(300000, ']'), "nested deeper");
  // 16 levels of meta are fine, 17 are not.
  EXPECT_EQ(Json(R"([{"id": "a", "image": "a.jpg", "meta": )" + Nested(16) + "}]").size(), 1u);
  BadJson(R"([{"id": "a", "image": "a.jpg", "meta": )" + Nested(17) + "}]", "nested deeper than 18 levels");
}

TEST(TargetList, ReadResolvesImagesAgainstTheListFolder) {
  const fs::path dir = fs::temp_directory_path() / ("mvkp_target_list_test_" + std::to_string(getpid()));
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "sub" / "list.CSV") << "id,image\na,a.jpg\nb,/abs/b.jpg\n";
  std::ofstream(dir / "sub" / "list.json") << R"([{"id": "c", "image": "../c.jpg"}])";
  std::ofstream(dir / "list.txt") << "id,image\n";
  const auto csv = ReadTargetList((dir / "sub" / "list.CSV").string());
  ASSERT_EQ(csv.size(), 2u);
  EXPECT_EQ(csv[0].second, (dir / "sub" / "a.jpg").string());
  EXPECT_EQ(csv[1].second, "/abs/b.jpg");
  const auto json = ReadTargetList((dir / "sub" / "list.json").string());
  ASSERT_EQ(json.size(), 1u);
  EXPECT_EQ(json[0].second, (dir / "sub" / "../c.jpg").string());
  ExpectError([&] { ReadTargetList((dir / "list.txt").string()); }, ErrorCode::kInvalidArgument, "expected a .csv or .json");
  ExpectError([&] { ReadTargetList((dir / "missing.csv").string()); }, ErrorCode::kIo, "cannot open list");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mvkp
