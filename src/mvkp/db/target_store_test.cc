#include "mvkp/db/target_store.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;

// Deterministic bytes that always include 0x00 and 0xFF.
std::vector<std::uint8_t> Pattern(std::size_t n, std::uint32_t seed) {
  std::vector<std::uint8_t> v(n);
  std::uint32_t x = seed * 2654435761u + 12345u;
  for (std::size_t i = 0; i < n; ++i) {
    x = x * 1664525u + 1013904223u;
    v[i] = std::uint8_t(x >> 24);
  }
  if (n > 0) v[0] = 0x00;
  if (n > 1) v[1] = 0xFF;
  if (n > 2) v[n - 1] = 0x00;
  return v;
}

TargetRecord Record(const std::string& id, std::size_t model_bytes = 1000, std::uint32_t seed = 1,
                    std::size_t image_bytes = 300) {
  TargetRecord r;
  r.info.id = id;
  r.info.title = "Title of " + id;
  r.info.artist = "Artist";
  r.info.year = "1889";
  r.info.url = "https://example.org/" + id;
  r.info.meta = R"({"room": 12, "tags": ["a", "b"]})";
  r.info.width = 640;
  r.info.height = 480;
  r.model = Pattern(model_bytes, seed);
  r.image = Pattern(image_bytes, seed + 1000);
  return r;
}

// Runs fn, expects Error(code) whose message contains `part`.
void ExpectError(const std::function<void()>& fn, ErrorCode code, const std::string& part) {
  try {
    fn();
    ADD_FAILURE() << "no error, expected one containing '" << part << "'";
  } catch (const Error& e) {
    EXPECT_EQ(int(e.code()), int(code)) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

// Raw SQLite access, for hand-made files and checks behind the store's back.
std::string Sql(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr), SQLITE_OK);
  sqlite3_busy_timeout(db, 5000);
  std::string out;
  char* err = nullptr;
  const int rc = sqlite3_exec(
      db, sql.c_str(),
      [](void* o, int n, char** vals, char**) {
        auto& s = *static_cast<std::string*>(o);
        for (int i = 0; i < n; ++i) {
          if (!s.empty()) s += '|';
          s.append(vals[i] ? vals[i] : "NULL");
        }
        return 0;
      },
      &out, &err);
  EXPECT_EQ(rc, SQLITE_OK) << sql << ": " << (err ? err : "");
  sqlite3_free(err);
  sqlite3_close(db);
  return out;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class TargetStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           ("mvkp_db_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    db_ = (dir_ / "targets.db").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  std::string db_;
};

TEST_F(TargetStoreTest, CreateAddListGetRemoveRoundTrip) {
  {
    TargetStore store = TargetStore::Create(db_);
    EXPECT_EQ(store.path(), db_);
    EXPECT_EQ(store.schema_version(), kTargetStoreSchemaVersion);
    EXPECT_EQ(store.Count(), 0u);
    EXPECT_TRUE(store.List().empty());

    store.Add(Record("b", 5000, 2));
    TargetRecord a = Record("a", 3000, 3, 0);  // no image
    a.info.meta = "{}";
    store.Add(a);
    TargetRecord u = Record("Mona-Lisa", 10, 4);
    u.info.title = "Mona Lisa — \xc3\xa9t\xc3\xa9";  // UTF-8 text
    store.Add(u);
    EXPECT_EQ(store.Count(), 3u);
    EXPECT_TRUE(store.Contains("a"));
    EXPECT_FALSE(store.Contains("c"));
  }
  TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
  const auto list = store.List();
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list[0].id, "Mona-Lisa");
  EXPECT_EQ(list[0].title, "Mona Lisa — \xc3\xa9t\xc3\xa9");
  EXPECT_EQ(list[1].id, "a");
  EXPECT_EQ(list[2].id, "b");
  const std::regex iso(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)");
  for (const auto& i : list) EXPECT_TRUE(std::regex_match(i.added_at, iso)) << i.added_at;

  const TargetRecord b = store.Get("b");
  const TargetRecord want = Record("b", 5000, 2);
  EXPECT_EQ(b.info.title, want.info.title);
  EXPECT_EQ(b.info.artist, "Artist");
  EXPECT_EQ(b.info.year, "1889");
  EXPECT_EQ(b.info.url, want.info.url);
  EXPECT_EQ(b.info.meta, want.info.meta);
  EXPECT_EQ(b.info.width, 640);
  EXPECT_EQ(b.info.height, 480);
  EXPECT_EQ(b.model, want.model);  // binary, with 0x00 and 0xFF
  EXPECT_EQ(b.image, want.image);
  EXPECT_EQ(b.model[0], 0x00);
  EXPECT_EQ(b.model[1], 0xFF);
  EXPECT_TRUE(store.Get("b", /*with_image=*/false).image.empty());
  EXPECT_EQ(store.Get("b", false).model, want.model);
  EXPECT_TRUE(store.Get("a").image.empty());
  EXPECT_EQ(store.Get("a").model, Pattern(3000, 3));

  const auto all = store.LoadAll();
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[2].info.id, "b");
  EXPECT_EQ(all[2].model, want.model);
  for (const auto& r : all) EXPECT_TRUE(r.image.empty());

  // UpdateInfo replaces the metadata only.
  TargetInfo info = b.info;
  info.title = "New title";
  info.meta = R"({"x": 1})";
  info.width = 1;  // ignored: the image is not replaced
  EXPECT_TRUE(store.UpdateInfo(info));
  const TargetRecord b2 = store.Get("b");
  EXPECT_EQ(b2.info.title, "New title");
  EXPECT_EQ(b2.info.meta, R"({"x": 1})");
  EXPECT_EQ(b2.info.width, 640);
  EXPECT_EQ(b2.info.added_at, b.info.added_at);
  EXPECT_EQ(b2.model, want.model);
  info.id = "nope";
  EXPECT_FALSE(store.UpdateInfo(info));
  info.id = "b";
  info.meta = "[1]";
  ExpectError([&] { store.UpdateInfo(info); }, ErrorCode::kInvalidArgument, "JSON object");

  EXPECT_TRUE(store.Remove("a"));
  EXPECT_FALSE(store.Remove("a"));
  EXPECT_EQ(store.Count(), 2u);
  ExpectError([&] { store.Get("a"); }, ErrorCode::kInvalidArgument, "no target 'a'");

  // The file is WAL, recognisable and versioned.
  EXPECT_EQ(Sql(db_, "PRAGMA journal_mode"), "wal");
  EXPECT_EQ(Sql(db_, "PRAGMA application_id"), std::to_string(0x4d564b50));
  EXPECT_EQ(Sql(db_, "PRAGMA user_version"), std::to_string(kTargetStoreSchemaVersion));

  // Moving keeps the connection.
  TargetStore moved = std::move(store);
  EXPECT_EQ(moved.Count(), 2u);
}

TEST_F(TargetStoreTest, CreateRefusesAnExistingPath) {
  TargetStore::Create(db_);
  ExpectError([&] { TargetStore::Create(db_); }, ErrorCode::kIo, db_);
  const std::string text = (dir_ / "notes.txt").string();
  std::ofstream(text) << "keep me";
  ExpectError([&] { TargetStore::Create(text); }, ErrorCode::kIo, "already exists");
  EXPECT_EQ(ReadFile(text), "keep me");
  ExpectError([&] { TargetStore::Create((dir_ / "no/such/dir/x.db").string()); }, ErrorCode::kIo,
              "cannot create");
}

TEST_F(TargetStoreTest, DuplicateIdLeavesTheStoreUnchanged) {
  TargetStore store = TargetStore::Create(db_);
  store.Add(Record("a", 1000, 1));
  const TargetRecord before = store.Get("a");
  ExpectError([&] { store.Add(Record("a", 2000, 9)); }, ErrorCode::kInvalidArgument, "target 'a' already exists");
  EXPECT_EQ(store.Count(), 1u);
  const TargetRecord after = store.Get("a");
  EXPECT_EQ(after.model, before.model);
  EXPECT_EQ(after.image, before.image);
  EXPECT_EQ(after.info.added_at, before.info.added_at);
  // The store still works (no transaction left open).
  store.Add(Record("b"));
  EXPECT_EQ(store.Count(), 2u);
}

TEST_F(TargetStoreTest, InvalidInputIsRejected) {
  TargetStore store = TargetStore::Create(db_);
  auto with_meta = [](const std::string& meta) {
    TargetRecord r = Record("m");
    r.info.meta = meta;
    return r;
  };
  ExpectError([&] { store.Add(with_meta("[1, 2]")); }, ErrorCode::kInvalidArgument, "JSON object");
  ExpectError([&] { store.Add(with_meta("{\"a\": ")); }, ErrorCode::kInvalidArgument, "not valid JSON");
  ExpectError([&] { store.Add(with_meta("")); }, ErrorCode::kInvalidArgument, "not valid JSON");
  ExpectError([&] { store.Add(with_meta("\"text\"")); }, ErrorCode::kInvalidArgument, "JSON object");
  ExpectError([&] { store.Add(Record("")); }, ErrorCode::kInvalidArgument, "empty");
  ExpectError([&] { store.Add(Record(std::string(257, 'x'))); }, ErrorCode::kInvalidArgument, "at most 256");
  ExpectError([&] { store.Add(Record("a\nb")); }, ErrorCode::kInvalidArgument, "control character");
  ExpectError([&] { store.Add(Record("a\tb")); }, ErrorCode::kInvalidArgument, "control character");
  ExpectError([&] { store.Add(Record("a\x7f")); }, ErrorCode::kInvalidArgument, "control character");
  ExpectError([&] { store.Add(Record("a\xff")); }, ErrorCode::kInvalidArgument, "UTF-8");
  ExpectError([&] { store.Add(Record("a\xc3")); }, ErrorCode::kInvalidArgument, "UTF-8");
  ExpectError([&] { store.Add(Record("m", 0)); }, ErrorCode::kInvalidArgument, "empty model");
  EXPECT_EQ(store.Count(), 0u);
  store.Add(Record(std::string(256, 'x')));
  store.Add(with_meta("{}"));
  EXPECT_EQ(store.Count(), 2u);
}

TEST_F(TargetStoreTest, NewIdsFollowTheGrammarAndFieldsTheirLimits) {
  TargetStore store = TargetStore::Create(db_);
  // Ids are URL path segments: ".." could not be deleted from a browser, bidi
  // controls make lookalikes.
  for (const char* id : {"..", ".", ".hidden", "-x", "a b", "a/b", "caf\xc3\xa9", "a\xe2\x80\xae" "b", "a?b", "a%2e"})
    ExpectError([&] { store.Add(Record(id)); }, ErrorCode::kInvalidArgument, "invalid target id");
  for (const char* id : {"a", "Mona_Lisa-1503.v2", "9"}) store.Add(Record(id));
  auto with = [](auto set) {
    TargetRecord r = Record("f");
    set(r.info);
    return r;
  };
  ExpectError([&] { store.Add(with([](TargetInfo& i) { i.url = "javascript:alert(1)"; })); },
              ErrorCode::kInvalidArgument, "url must be an absolute http");
  ExpectError([&] { store.Add(with([](TargetInfo& i) { i.url = "data:text/html,x"; })); }, ErrorCode::kInvalidArgument,
              "url");
  ExpectError([&] { store.Add(with([](TargetInfo& i) { i.url = "https://"; })); }, ErrorCode::kInvalidArgument, "url");
  ExpectError([&] { store.Add(with([](TargetInfo& i) { i.url = "https://a.b/\"x"; })); }, ErrorCode::kInvalidArgument,
              "url");
  ExpectError([&] { store.Add(with([](TargetInfo& i) { i.title = std::string(5 << 20, 't'); })); },
              ErrorCode::kInvalidArgument, "title is 5242880 bytes, at most 1000");
  ExpectError([&] { store.Add(with([](TargetInfo& i) { i.artist = "a\x1b[2J"; })); }, ErrorCode::kInvalidArgument,
              "control character");
  auto deep = [](int levels) {
    std::string d;
    for (int k = 0; k < levels; ++k) d += "{\"a\":";
    return d + "1" + std::string(levels, '}');
  };
  ExpectError([&] { store.Add(with([&](TargetInfo& i) { i.meta = deep(17); })); }, ErrorCode::kInvalidArgument,
              "nested deeper than 16 levels");
  ExpectError([&] { store.Add(with([&](TargetInfo& i) { i.meta = deep(100000); })); }, ErrorCode::kInvalidArgument,
              "at most 65536");
  EXPECT_EQ(store.Count(), 3u);
  store.Add(with([](TargetInfo& i) { i.url = "HTTPS://example.org/a?b=c#d"; }));
  // Updates check the fields but not the id grammar: older ids stay editable.
  TargetInfo upd = store.Get("f", false).info;
  upd.url = "javascript:alert(1)";
  ExpectError([&] { store.UpdateInfo(upd); }, ErrorCode::kInvalidArgument, "url");
  EXPECT_EQ(store.Get("f", false).info.url, "HTTPS://example.org/a?b=c#d");
  upd.url = "";
  EXPECT_NO_THROW(ValidateTargetInfo(upd, /*new_id=*/false));
  upd.id = "..";
  EXPECT_NO_THROW(ValidateTargetInfo(upd, /*new_id=*/false));
  EXPECT_THROW(ValidateTargetInfo(upd, /*new_id=*/true), Error);
}

TEST_F(TargetStoreTest, ReadOnlyStoreReadsAndRefusesWrites) {
  {
    TargetStore store = TargetStore::Create(db_);
    store.Add(Record("a", 4000, 5));
    store.Add(Record("b", 4000, 6));
  }
  const std::string bytes = ReadFile(db_);
  TargetStore ro = TargetStore::Open(db_);  // read-only by default
  EXPECT_EQ(ro.schema_version(), kTargetStoreSchemaVersion);
  ASSERT_EQ(ro.List().size(), 2u);
  EXPECT_EQ(ro.Get("b").model, Pattern(4000, 6));
  EXPECT_EQ(ro.LoadAll().size(), 2u);
  ExpectError([&] { ro.Add(Record("c")); }, ErrorCode::kInvalidArgument, "DB: opened read-only");
  ExpectError([&] { ro.AddAll({Record("c")}); }, ErrorCode::kInvalidArgument, "DB: opened read-only");
  ExpectError([&] { ro.Remove("a"); }, ErrorCode::kInvalidArgument, "DB: opened read-only");
  ExpectError([&] { ro.UpdateInfo(Record("a").info); }, ErrorCode::kInvalidArgument, "DB: opened read-only");
  EXPECT_EQ(ro.Count(), 2u);
  EXPECT_EQ(ReadFile(db_), bytes);
}

// A reader sees data_version change after each commit by another connection
// (as a server watching the file does), and not after its own reads.
TEST_F(TargetStoreTest, DataVersionChangesWithOtherConnectionsCommits) {
  TargetStore writer = TargetStore::Create(db_);
  writer.Add(Record("a", 100, 1));
  const TargetStore reader = TargetStore::Open(db_);
  const std::uint64_t v0 = reader.DataVersion();
  EXPECT_EQ(reader.Count(), 1u);
  EXPECT_EQ(reader.DataVersion(), v0);
  writer.Add(Record("b", 100, 2));
  const std::uint64_t v1 = reader.DataVersion();
  EXPECT_NE(v1, v0);
  EXPECT_EQ(reader.DataVersion(), v1);
  TargetInfo info = writer.Get("a", false).info;
  info.title = "renamed";
  ASSERT_TRUE(writer.UpdateInfo(info));
  const std::uint64_t v2 = reader.DataVersion();
  EXPECT_NE(v2, v1);
  ASSERT_TRUE(writer.Remove("b"));
  EXPECT_NE(reader.DataVersion(), v2);
  // A failed write (duplicate id) commits nothing.
  const std::uint64_t v3 = reader.DataVersion();
  EXPECT_THROW(writer.Add(Record("a", 100, 3)), Error);
  EXPECT_EQ(reader.DataVersion(), v3);
}

TEST_F(TargetStoreTest, OpenRejectsWhatIsNotOurs) {
  using M = TargetStore::Mode;
  for (M mode : {M::kReadOnly, M::kReadWrite}) {
    SCOPED_TRACE(mode == M::kReadOnly ? "read-only" : "read-write");
    ExpectError([&] { TargetStore::Open((dir_ / "missing.db").string(), mode); }, ErrorCode::kIo,
                "DB: no such database");
    ExpectError([&] { TargetStore::Open(dir_.string(), mode); }, ErrorCode::kIo, "not a regular file");

    const std::string text = (dir_ / "text.db").string();
    std::ofstream(text) << "this is a text file, not a database at all. " << std::string(200, 'x');
    const std::string text_bytes = ReadFile(text);
    ExpectError([&] { TargetStore::Open(text, mode); }, ErrorCode::kBadModel, "DB: not an mvkp target database");
    EXPECT_EQ(ReadFile(text), text_bytes);

    const std::string empty = (dir_ / "empty.db").string();
    std::ofstream(empty).close();
    ExpectError([&] { TargetStore::Open(empty, mode); }, ErrorCode::kBadModel, "not an mvkp target database");
    EXPECT_EQ(fs::file_size(empty), 0u);

    const std::string foreign = (dir_ / "foreign.db").string();
    if (!fs::exists(foreign)) Sql(foreign, "CREATE TABLE other(x INTEGER); INSERT INTO other VALUES (7);");
    ExpectError([&] { TargetStore::Open(foreign, mode); }, ErrorCode::kBadModel, "not an mvkp target database");
    EXPECT_EQ(Sql(foreign, "PRAGMA journal_mode"), "delete");  // untouched
    EXPECT_EQ(Sql(foreign, "SELECT x FROM other"), "7");

    // Ours, but from the future.
    const std::string future = (dir_ / "future.db").string();
    if (!fs::exists(future)) {
      TargetStore::Create(future);
      Sql(future, "PRAGMA user_version = 99");
    }
    ExpectError([&] { TargetStore::Open(future, mode); }, ErrorCode::kBadModel,
                "schema version 99 is newer than this build's " + std::to_string(kTargetStoreSchemaVersion));

    // Our application_id and version, but no targets table.
    const std::string hollow = (dir_ / "hollow.db").string();
    if (!fs::exists(hollow)) {
      Sql(hollow, "PRAGMA application_id = " + std::to_string(0x4d564b50) + "; PRAGMA user_version = " +
                      std::to_string(kTargetStoreSchemaVersion) + "; CREATE TABLE t(x);");
    }
    ExpectError([&] { TargetStore::Open(hollow, mode); }, ErrorCode::kBadModel, "not an mvkp target database");
  }
}

TEST_F(TargetStoreTest, EncodingsAreStoredWithTheTargetAndRemovedWithIt) {
  {
    TargetStore store = TargetStore::Create(db_);
    TargetRecord a = Record("a", 100, 1);
    a.encodings.push_back({"words", Pattern(40, 7)});
    a.encodings.push_back({"other", Pattern(10, 8)});
    store.Add(a);
    store.Add(Record("b", 100, 2));  // none
    TargetRecord dup = Record("a", 100, 3);
    dup.encodings.push_back({"words", Pattern(40, 9)});
    EXPECT_THROW(store.Add(dup), Error);  // nothing of it written
  }
  TargetStore ro = TargetStore::Open(db_);
  auto words = ro.LoadEncodings("words");
  ASSERT_EQ(words.size(), 1u);
  EXPECT_EQ(words[0].first.id, "a");
  EXPECT_EQ(words[0].second, Pattern(40, 7));
  EXPECT_EQ(ro.LoadEncodings("other").size(), 1u);
  EXPECT_TRUE(ro.LoadEncodings("none").empty());
  {
    TargetStore rw = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
    EXPECT_TRUE(rw.Remove("a"));
  }
  EXPECT_TRUE(TargetStore::Open(db_).LoadEncodings("words").empty());
  EXPECT_EQ(Sql(db_, "SELECT count(*) FROM encodings"), "0");
}

TEST_F(TargetStoreTest, VersionOneFilesAreReadAsTheyAreAndMigratedOnWrite) {
  {
    TargetStore store = TargetStore::Create(db_);
    store.Add(Record("a", 100, 1));
  }
  // What schema 1 looked like: no encodings table.
  Sql(db_, "DROP TABLE encodings; PRAGMA user_version = 1;");
  {
    TargetStore ro = TargetStore::Open(db_);
    EXPECT_EQ(ro.schema_version(), 1);
    EXPECT_EQ(ro.LoadAll().size(), 1u);
    EXPECT_TRUE(ro.LoadEncodings("words").empty());
  }
  {
    TargetStore rw = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
    EXPECT_EQ(rw.schema_version(), kTargetStoreSchemaVersion);
    TargetRecord b = Record("b", 100, 2);
    b.encodings.push_back({"words", Pattern(30, 4)});
    rw.Add(b);
  }
  EXPECT_EQ(TargetStore::Open(db_).LoadEncodings("words").size(), 1u);
  EXPECT_EQ(TargetStore::Open(db_).Get("a").model, Pattern(100, 1));
}

TEST_F(TargetStoreTest, OlderSchemaIsMigratedOnReadWriteOpen) {
  // A version-0 file: our application_id, no schema yet.
  Sql(db_, "PRAGMA application_id = " + std::to_string(0x4d564b50) + "; PRAGMA user_version = 0;");
  ExpectError([&] { TargetStore::Open(db_); }, ErrorCode::kBadModel, "schema version 0 is older");
  {
    TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
    EXPECT_EQ(store.schema_version(), kTargetStoreSchemaVersion);
    store.Add(Record("a", 100, 1));
  }
  EXPECT_EQ(Sql(db_, "PRAGMA user_version"), std::to_string(kTargetStoreSchemaVersion));
  EXPECT_EQ(Sql(db_, "PRAGMA journal_mode"), "wal");
  TargetStore ro = TargetStore::Open(db_);
  EXPECT_EQ(ro.Get("a").model, Pattern(100, 1));
}

TEST_F(TargetStoreTest, AddAllIsAllOrNone) {
  TargetStore store = TargetStore::Create(db_);
  store.Add(Record("a"));
  TargetRecord bad = Record("c");
  bad.info.meta = "not json";
  ExpectError([&] { store.AddAll({Record("b"), bad, Record("d")}); }, ErrorCode::kInvalidArgument, "meta");
  EXPECT_EQ(store.Count(), 1u);
  // A duplicate found by the database mid-transaction rolls back the earlier inserts.
  ExpectError([&] { store.AddAll({Record("b"), Record("c"), Record("a"), Record("d")}); },
              ErrorCode::kInvalidArgument, "target 'a' already exists");
  EXPECT_EQ(store.Count(), 1u);
  EXPECT_FALSE(store.Contains("b"));
  ExpectError([&] { store.AddAll({Record("b"), Record("b")}); }, ErrorCode::kInvalidArgument,
              "target 'b' already exists");
  EXPECT_EQ(store.Count(), 1u);
  store.AddAll({Record("d"), Record("b", 50, 7), Record("c")});
  EXPECT_EQ(store.Count(), 4u);
  EXPECT_EQ(store.Get("b").model, Pattern(50, 7));
  store.AddAll({});
  EXPECT_EQ(store.Count(), 4u);
}

// --- multi-process tests ----------------------------------------------------

constexpr std::size_t kBig = 20u << 20;  // 20 MB model

std::uint32_t SeedOf(int round, int k) { return std::uint32_t(1000 * round + k + 17); }
std::string BigId(int round, int k) { return "big_" + std::to_string(round) + "_" + std::to_string(k); }

// Reads every byte left in the pipe (the writer has exited).
std::string Drain(int fd) {
  std::string s;
  char buf[256];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) s.append(buf, std::size_t(n));
  return s;
}

// A child adds 20 MB targets in a loop and is SIGKILLed at a varying moment;
// the store must open cleanly with only complete targets and keep the old ones.
TEST_F(TargetStoreTest, SurvivesAWriterKilledMidTransaction) {
  {
    TargetStore store = TargetStore::Create(db_);
    store.Add(Record("early_1", 70000, 1));
    store.Add(Record("early_2", 3000, 2));
  }
  // Time one 20 MB add here, then kill at fractions of that duration so the
  // kills land before, inside and after the write whatever the disk speed.
  double add_ms = 0;
  {
    TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
    TargetRecord r = Record("probe", 0);
    r.model = Pattern(kBig, 99);
    const auto t0 = std::chrono::steady_clock::now();
    store.Add(r);
    add_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_TRUE(store.Remove("probe"));
  }
  std::vector<int> delays_ms;
  for (double f : {0.0, 0.1, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0, 2.5}) delays_ms.push_back(int(f * add_ms));
  int killed_in_flight = 0, committed_total = 0;
  for (int round = 0; round < int(delays_ms.size()); ++round) {
    SCOPED_TRACE("round " + std::to_string(round) + ", kill after " + std::to_string(delays_ms[round]) + " ms");
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {  // child: writer
      ::close(fds[0]);
      try {
        TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
        for (int k = 0;; ++k) {
          TargetRecord r = Record(BigId(round, k), 0, 0, 1000);
          r.model = Pattern(kBig, SeedOf(round, k));
          if (::write(fds[1], "B", 1) != 1) ::_exit(4);  // begin
          store.Add(r);
          if (::write(fds[1], "D", 1) != 1) ::_exit(4);  // committed
        }
      } catch (...) {
        ::_exit(3);
      }
    }
    ::close(fds[1]);
    char c = 0;
    ASSERT_EQ(::read(fds[0], &c, 1), 1);  // the first add has started
    std::this_thread::sleep_for(std::chrono::milliseconds(delays_ms[round]));
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "child exited with " << status;
    const std::string events = "B" + Drain(fds[0]);
    ::close(fds[0]);
    int begun = 0, done = 0;
    for (char e : events) (e == 'B' ? begun : done)++;
    const bool in_flight = begun > done;
    killed_in_flight += in_flight;
    committed_total += done;

    // Read-only first: WAL recovery must work without a writer.
    {
      TargetStore ro = TargetStore::Open(db_);
      EXPECT_EQ(ro.Get("early_1").model, Pattern(70000, 1));
    }
    EXPECT_EQ(Sql(db_, "PRAGMA integrity_check"), "ok");
    TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
    std::set<std::string> ids;
    for (const auto& i : store.List()) ids.insert(i.id);
    EXPECT_TRUE(ids.count("early_1") && ids.count("early_2"));
    EXPECT_EQ(store.Get("early_1").model, Pattern(70000, 1));
    EXPECT_EQ(store.Get("early_2").model, Pattern(3000, 2));
    EXPECT_EQ(store.Get("early_2").image, Record("early_2", 3000, 2).image);
    for (int k = 0; k < begun; ++k) {
      const std::string id = BigId(round, k);
      if (k < done) {
        ASSERT_TRUE(ids.count(id)) << id << " was committed but is missing";
      }
      if (ids.count(id)) {
        const TargetRecord r = store.Get(id);
        EXPECT_TRUE(r.model == Pattern(kBig, SeedOf(round, k))) << id << " is incomplete";
        EXPECT_EQ(r.image, Record(id, 0, 0, 1000).image);
        ids.erase(id);
      }
    }
    ids.erase("early_1");
    ids.erase("early_2");
    EXPECT_TRUE(ids.empty()) << "unexpected target " << *ids.begin();
    // Keep the file small for the next round.
    for (int k = 0; k < begun; ++k) store.Remove(BigId(round, k));
    EXPECT_EQ(store.Count(), 2u);
  }
  std::printf("[ info ] one 20 MB add: %.0f ms; %d of %zu kills hit an add in flight; %d adds committed\n",
              add_ms, killed_in_flight, delays_ms.size(), committed_total);
  EXPECT_GE(killed_in_flight, 4) << "the kills never interrupted a write; the test proves nothing";
}

// A reader (its own connection, read-only) lists while another process is
// inside a long write transaction: no error, and it sees the old or the new
// state, never a part. A second writer waits (busy timeout) and succeeds.
TEST_F(TargetStoreTest, ReadersWorkWhileAnotherProcessWrites) {
  {
    TargetStore store = TargetStore::Create(db_);
    store.Add(Record("a"));
  }
  constexpr int kBatch = 4;
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {  // child: one long transaction of kBatch x 20 MB
    ::close(fds[0]);
    try {
      std::vector<TargetRecord> batch;
      for (int k = 0; k < kBatch; ++k) {
        batch.push_back(Record("w" + std::to_string(k), 0, 0, 10));
        batch.back().model = Pattern(kBig, SeedOf(9, k));
      }
      TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
      if (::write(fds[1], "B", 1) != 1) ::_exit(4);
      store.AddAll(batch);
      if (::write(fds[1], "D", 1) != 1) ::_exit(4);
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }
  ::close(fds[1]);
  char c = 0;
  ASSERT_EQ(::read(fds[0], &c, 1), 1);
  ASSERT_EQ(c, 'B');
  ::fcntl(fds[0], F_SETFL, O_NONBLOCK);

  const std::vector<std::string> old_ids = {"a"};
  std::vector<std::string> new_ids = {"a"};
  for (int k = 0; k < kBatch; ++k) new_ids.push_back("w" + std::to_string(k));
  TargetStore reader = TargetStore::Open(db_);
  int lists_during = 0, old_seen = 0, new_seen = 0;
  bool committed = false;
  const auto t0 = std::chrono::steady_clock::now();
  while (!committed && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30)) {
    std::vector<std::string> ids;
    for (const auto& i : reader.List()) ids.push_back(i.id);  // throws on SQLITE_BUSY
    const std::size_t n = reader.Count();
    EXPECT_TRUE(ids == old_ids || ids == new_ids) << ids.size() << " targets";
    EXPECT_TRUE(n == old_ids.size() || n == new_ids.size());
    committed = ::read(fds[0], &c, 1) == 1;  // 'D'
    if (!committed) {
      ++lists_during;
      (ids == old_ids ? old_seen : new_seen)++;
    }
  }
  ASSERT_TRUE(committed);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  ::close(fds[0]);
  std::printf("[ info ] %d lists during the write (%d old, %d new)\n", lists_during, old_seen, new_seen);
  EXPECT_GT(old_seen, 0) << "the reader never overlapped the write transaction";

  std::vector<std::string> ids;
  for (const auto& i : reader.List()) ids.push_back(i.id);
  EXPECT_EQ(ids, new_ids);
  EXPECT_EQ(reader.Get("w3").model, Pattern(kBig, SeedOf(9, 3)));
}

TEST_F(TargetStoreTest, SecondWriterWaitsForTheFirst) {
  TargetStore::Create(db_);
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {  // child: holds the write lock for 1 s
    ::close(fds[0]);
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(db_.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) ::_exit(3);
    if (sqlite3_exec(db, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) != SQLITE_OK) ::_exit(3);
    if (::write(fds[1], "B", 1) != 1) ::_exit(4);
    std::this_thread::sleep_for(std::chrono::seconds(1));
    sqlite3_exec(db, "COMMIT", nullptr, nullptr, nullptr);
    sqlite3_close(db);
    ::_exit(0);
  }
  ::close(fds[1]);
  char c = 0;
  ASSERT_EQ(::read(fds[0], &c, 1), 1);
  ::close(fds[0]);
  TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
  const auto t0 = std::chrono::steady_clock::now();
  store.Add(Record("x"));  // waits for the child's COMMIT
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_GT(waited, 0.5);
  EXPECT_EQ(store.Count(), 1u);
}

TEST_F(TargetStoreTest, RestoreKeepsAddedAtAndReplaceImageSwapsModelAndEncodings) {
  TargetStore store = TargetStore::Create(db_);
  TargetRecord r = Record("a");
  r.info.added_at = "2001-02-03T04:05:06Z";
  r.encodings = {{"words", Pattern(50, 7)}, {"quality", Pattern(20, 8)}};
  store.Restore({r});
  EXPECT_EQ(store.Get("a").info.added_at, "2001-02-03T04:05:06Z");
  EXPECT_EQ(store.Encodings("a"), (std::vector<std::pair<std::string, std::vector<std::uint8_t>>>{
                                      {"quality", Pattern(20, 8)}, {"words", Pattern(50, 7)}}));
  TargetRecord no_date = Record("b");
  ExpectError([&] { store.Restore({no_date}); }, ErrorCode::kInvalidArgument, "added_at");
  EXPECT_FALSE(store.Contains("b"));

  TargetRecord n = Record("a", 500, 9, 200);
  n.info.title = "ignored";
  n.info.width = 100;
  n.info.height = 50;
  n.encodings = {{"words", Pattern(30, 10)}};
  ASSERT_TRUE(store.ReplaceImage(n));
  const TargetRecord got = store.Get("a");
  EXPECT_EQ(got.model, n.model);
  EXPECT_EQ(got.image, n.image);
  EXPECT_EQ(got.info.width, 100);
  EXPECT_EQ(got.info.title, "Title of a");  // metadata stays
  EXPECT_NE(got.info.added_at, "2001-02-03T04:05:06Z");
  EXPECT_EQ(store.Encodings("a").size(), 1u);
  n.info.id = "ghost";
  EXPECT_FALSE(store.ReplaceImage(n));
  EXPECT_FALSE(store.Contains("ghost"));
}

TEST_F(TargetStoreTest, BackupRefusesToOverwriteUnlessForcedAndNeverTheDatabaseItself) {
  TargetStore::Create(db_).Add(Record("a"));
  const std::string out = (dir_ / "copy.db").string();
  EXPECT_EQ(BackupTargetStore(db_, out).targets, 1u);
  TargetStore::Open(db_, TargetStore::Mode::kReadWrite).Add(Record("b", 1000, 2));
  ExpectError([&] { BackupTargetStore(db_, out); }, ErrorCode::kIo, "already exists");
  EXPECT_EQ(TargetStore::Open(out).Count(), 1u);  // the old copy is intact
  BackupOptions force;
  force.overwrite = true;
  EXPECT_EQ(BackupTargetStore(db_, out, force).targets, 2u);
  EXPECT_EQ(TargetStore::Open(out).Count(), 2u);
  ExpectError([&] { BackupTargetStore(db_, db_, force); }, ErrorCode::kIo, "the database itself");
  EXPECT_EQ(TargetStore::Open(db_).Count(), 2u);
  ExpectError([&] { BackupTargetStore((dir_ / "none.db").string(), (dir_ / "x.db").string()); }, ErrorCode::kIo,
              "no such database");
  EXPECT_FALSE(fs::exists(dir_ / "x.db"));
  for (const auto& e : fs::directory_iterator(dir_))  // no temporary files left behind
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

// Issue 20: "A backup taken during 16 concurrent admin edits restores to an
// integrity-checked database holding every committed edit". Each thread adds
// targets (a row and its encoding: two statements in one transaction) and
// edits its own seed target's title, on its own connection, while the backup
// copies the file a few pages per step (so writes restart it).
TEST_F(TargetStoreTest, BackupDuringSixteenConcurrentEditsHoldsEveryEditCommittedBeforeIt) {
  constexpr int kThreads = 16, kEdits = 12;
  {
    TargetStore store = TargetStore::Create(db_);
    for (int t = 0; t < kThreads; ++t) store.Add(Record("seed-" + std::to_string(t), 200, 5000 + t));
  }
  auto id_of = [](int t, int i) { return "t" + std::to_string(t) + "-" + std::to_string(i); };
  auto model_of = [](int t, int i) { return Pattern(30000 + 37 * i, 100 * t + i); };  // ~8 pages each
  auto words_of = [](int t, int i) { return Pattern(120 + i, 7000 + 100 * t + i); };
  struct Edit {
    int thread, index;
  };
  std::mutex mu;
  std::condition_variable cv;
  std::vector<Edit> committed;  // in commit order
  std::atomic<int> errors{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      try {
        TargetStore store = TargetStore::Open(db_, TargetStore::Mode::kReadWrite);
        for (int i = 0; i < kEdits; ++i) {
          if (i % 3 == 2) {
            TargetInfo info = store.Get("seed-" + std::to_string(t), false).info;
            info.title = "edit " + std::to_string(i);
            store.UpdateInfo(info);
          } else {
            TargetRecord r = Record(id_of(t, i));
            r.model = model_of(t, i);
            r.encodings = {{"words", words_of(t, i)}};
            store.Add(r);
          }
          std::lock_guard<std::mutex> lock(mu);
          committed.push_back({t, i});
          cv.notify_all();
        }
      } catch (const std::exception& e) {
        ADD_FAILURE() << "thread " << t << ": " << e.what();
        ++errors;
        std::lock_guard<std::mutex> lock(mu);
        cv.notify_all();
      }
    });
  }
  std::vector<Edit> before;
  {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait(lock, [&] { return committed.size() >= std::size_t(3 * kThreads) || errors > 0; });
    before = committed;  // every edit here committed before the backup starts
  }
  const std::string out = (dir_ / "backup.db").string();
  BackupOptions o;
  o.pages_per_step = 1;  // many steps, so that commits land between them
  BackupReport report;
  EXPECT_NO_THROW(report = BackupTargetStore(db_, out, o));
  {
    std::lock_guard<std::mutex> lock(mu);  // how much the backup overlapped, for the record
    RecordProperty("edits_before_backup", int(before.size()));
    RecordProperty("edits_during_backup", int(committed.size() - before.size()));
    RecordProperty("backup_restarts", report.restarts);
  }
  for (auto& th : threads) th.join();
  ASSERT_EQ(errors.load(), 0);
  ASSERT_EQ(committed.size(), std::size_t(kThreads * kEdits));

  EXPECT_EQ(Sql(out, "PRAGMA integrity_check"), "ok");
  const TargetStore copy = TargetStore::Open(out);
  EXPECT_EQ(copy.Count(), report.targets);
  for (const Edit& e : before) {
    if (e.index % 3 == 2) {
      const std::string title = copy.Get("seed-" + std::to_string(e.thread), false).info.title;
      ASSERT_EQ(title.rfind("edit ", 0), 0u) << title;
      EXPECT_GE(std::stoi(title.substr(5)), e.index) << "thread " << e.thread;  // that edit or a later one
    } else {
      EXPECT_TRUE(copy.Contains(id_of(e.thread, e.index))) << id_of(e.thread, e.index) << " committed before the backup";
    }
  }
  // Whatever the copy holds is whole: each added target with its own model and encoding.
  std::size_t added = 0;
  for (const TargetInfo& info : copy.List()) {
    if (info.id.rfind("seed-", 0) == 0) continue;
    ++added;
    const int t = std::stoi(info.id.substr(1, info.id.find('-') - 1)), i = std::stoi(info.id.substr(info.id.find('-') + 1));
    EXPECT_EQ(copy.Get(info.id, false).model, model_of(t, i)) << info.id;
    const auto enc = copy.Encodings(info.id);
    ASSERT_EQ(enc.size(), 1u) << info.id << ": half an edit";
    EXPECT_EQ(enc[0].second, words_of(t, i)) << info.id;
  }
  EXPECT_EQ(copy.Count(), kThreads + added);
  EXPECT_EQ(Sql(out, "SELECT count(*) FROM encodings WHERE id NOT IN (SELECT id FROM targets)"), "0");
}

}  // namespace
}  // namespace mvkp
