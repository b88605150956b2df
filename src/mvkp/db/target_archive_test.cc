#include "mvkp/db/target_archive.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> Bytes(std::size_t n, int seed) {
  std::vector<std::uint8_t> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = std::uint8_t((i * 131 + std::size_t(seed) * 7) >> 1);
  return v;
}

std::string Slurp(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
void Spit(const std::string& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

class TargetArchiveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("mvkp_archive_" + std::to_string(::getpid()) + "_" +
                                            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    db_ = (dir_ / "a.db").string();
    TargetStore s = TargetStore::Create(db_);
    for (int i = 0; i < 3; ++i) {
      TargetRecord r;
      // An id longer than a tar name may be: files are named by entry number.
      r.info.id = i == 2 ? std::string(200, 'x') : "t" + std::to_string(i);
      r.info.title = "Title, \"quoted\" " + std::to_string(i);
      r.info.meta = R"({"room": 3, "tags": ["a"]})";
      r.info.width = 100 + i;
      r.info.height = 50;
      r.model = Bytes(3000 + 700 * std::size_t(i), i);
      r.image = i == 1 ? std::vector<std::uint8_t>() : Bytes(513, i + 10);  // one empty image
      r.encodings = {{"words", Bytes(77, i + 20)}};
      s.Add(r);
    }
    tar_ = (dir_ / "a.tar").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  void ExpectBad(const std::string& path, const std::string& part) {
    try {
      ReadTargetArchive(path);
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  }

  fs::path dir_;
  std::string db_, tar_;
};

TEST_F(TargetArchiveTest, RoundTripRestoresEqualRecords) {
  EXPECT_EQ(ExportTargetArchive(db_, tar_), 3u);
  EXPECT_TRUE(IsTargetArchive(tar_));
  const auto entries = ReadTargetArchive(tar_);
  ASSERT_EQ(entries.size(), 3u);
  const TargetStore src = TargetStore::Open(db_);
  std::vector<TargetRecord> records;
  for (const auto& e : entries) {
    ASSERT_TRUE(e.error.empty()) << e.error;
    const TargetRecord want = src.Get(e.record.info.id);
    EXPECT_EQ(e.record.info.title, want.info.title);
    EXPECT_EQ(e.record.info.meta, R"({"room": 3, "tags": ["a"]})");  // the stored text
    EXPECT_EQ(e.record.info.added_at, want.info.added_at);
    EXPECT_EQ(e.record.info.width, want.info.width);
    EXPECT_EQ(e.record.model, want.model);
    EXPECT_EQ(e.record.image, want.image);
    EXPECT_EQ(e.record.encodings, src.Encodings(want.info.id));
    records.push_back(e.record);
  }
  const std::string restored = (dir_ / "b.db").string();
  TargetStore::Create(restored).Restore(records);
  const TargetStore b = TargetStore::Open(restored);
  ASSERT_EQ(b.Count(), 3u);
  for (const auto& info : src.List()) {
    EXPECT_EQ(b.Get(info.id).info.added_at, info.added_at);
    EXPECT_EQ(b.Get(info.id).model, src.Get(info.id).model);
  }
  // No snapshot left beside the archive.
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_EQ(e.path().string().find("snapshot"), std::string::npos) << e.path();
  try {
    ExportTargetArchive(db_, tar_);
    ADD_FAILURE() << "overwrote";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("already exists"), std::string::npos);
  }
  EXPECT_EQ(ExportTargetArchive(db_, tar_, /*overwrite=*/true), 3u);
}

TEST_F(TargetArchiveTest, DamageIsFoundWholeOrPerEntry) {
  ExportTargetArchive(db_, tar_);
  const std::string good = Slurp(tar_);
  const std::string p = (dir_ / "bad.tar").string();
  // Truncated anywhere: an error for the whole archive.
  for (std::size_t cut : {std::size_t(0), std::size_t(100), std::size_t(512), good.size() / 2, good.size() - 1024}) {
    Spit(p, good.substr(0, cut));
    ExpectBad(p, cut == 0 ? "empty" : "truncated");
  }
  // A damaged tar header.
  std::string h = good;
  h[10] ^= 1;
  Spit(p, h);
  ExpectBad(p, "damaged tar header");
  // A tar without our manifest.
  Spit(p, std::string(1024, '\0'));
  ExpectBad(p, "mvkp-archive.json");
  // One changed byte in entry 2's model: that entry is reported, the others are good.
  std::string m = good;
  m[m.find("targets/000002/model") + 512 + 7] ^= 0x10;
  Spit(p, m);
  const auto entries = ReadTargetArchive(p);
  ASSERT_EQ(entries.size(), 3u);
  EXPECT_TRUE(entries[0].error.empty());
  EXPECT_NE(entries[1].error.find("damaged"), std::string::npos) << entries[1].error;
  EXPECT_TRUE(entries[2].error.empty());
}

}  // namespace
}  // namespace mvkp
