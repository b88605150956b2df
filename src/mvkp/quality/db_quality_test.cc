#include "mvkp/quality/db_quality.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "mvkp/core/error.h"
#include "mvkp/recognize/target_db.h"

#include "test_samples.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;
using mvkp::testing::Sample;

const char* const kSamples[] = {"astronaut", "baboon", "building", "coffee", "fruits", "starry_night"};

QualityOptions Fast() {
  QualityOptions o;
  o.test_views = 8;
  return o;
}

std::vector<std::uint8_t> Png(const cv::Mat& gray) {
  std::vector<std::uint8_t> out;
  cv::imencode(".png", gray, out);
  return out;
}

// A database of the six samples plus `coffee_copy`: coffee cropped by 10 %
// at each side and brightened by 30 grey levels (what a second photo of the
// same painting, added by mistake, looks like).
class DatabaseQuality : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mvkp_db_quality_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
    fs::create_directories(dir_);
    db_ = (dir_ / "t.db").string();
    TargetStore store = TargetStore::Create(db_);
    for (const char* name : kSamples) Add(store, name, Sample(std::string(name) + ".jpg"));
    const cv::Mat coffee = Sample("coffee.jpg");
    const cv::Rect crop(coffee.cols / 10, coffee.rows / 10, coffee.cols * 8 / 10, coffee.rows * 8 / 10);
    cv::Mat copy;
    coffee(crop).convertTo(copy, CV_8U, 1.0, 30);
    Add(store, "coffee_copy", copy);
  }
  void TearDown() override { fs::remove_all(dir_); }
  void Add(TargetStore& store, const std::string& id, const cv::Mat& gray) {
    TargetInfo info;
    info.id = id;
    images_[id] = gray;
    store.Add(MakeTargetRecord(info, Png(gray), gray, DbTrainDefaults(), id));
  }
  fs::path dir_;
  std::string db_;
  std::map<std::string, cv::Mat> images_;
};

TEST_F(DatabaseQuality, FindsTheNearDuplicateAndNoPairAmongDistinctSamples) {
  DatabaseQualityOptions o;
  o.quality = Fast();
  int last = 0;
  o.progress = [&](int done, int total) {
    EXPECT_EQ(done, last + 1);
    EXPECT_EQ(total, 7);
    last = done;
  };
  const DatabaseQualityReport r = AssessDatabase(db_, o);
  EXPECT_EQ(last, 7);
  ASSERT_EQ(r.exhibits.size(), 7u);
  // Each score is the one AssessTarget gives the image itself (stored as a
  // lossless PNG, so the decoded pixels are the same).
  for (const auto& e : r.exhibits) {
    SCOPED_TRACE(e.info.id);
    EXPECT_TRUE(e.error.empty()) << e.error;
    ASSERT_TRUE(e.assessed);
    const QualityReport direct = AssessTarget(images_.at(e.info.id), o.quality);
    EXPECT_EQ(e.quality.score, direct.score);
    EXPECT_EQ(e.quality.eligible_tracks, direct.eligible_tracks);
    EXPECT_EQ(e.quality.detection_rate, direct.detection_rate);
  }
  // The copy and its original find each other; no other pair appears.
  ASSERT_FALSE(r.pairs.empty());
  bool forward = false, backward = false;
  for (const auto& p : r.pairs) {
    SCOPED_TRACE(p.a + " -> " + p.b);
    const bool dup = (p.a == "coffee" && p.b == "coffee_copy") || (p.a == "coffee_copy" && p.b == "coffee");
    EXPECT_TRUE(dup);
    EXPECT_EQ(p.probes, 1 + o.synthetic_views);
    EXPECT_GE(p.inliers, o.recognizer.min_inliers);
    forward |= p.a == "coffee";
    backward |= p.a == "coffee_copy";
  }
  EXPECT_TRUE(forward);
  EXPECT_TRUE(backward);
}

TEST_F(DatabaseQuality, PairsOnlySkipsTheScores) {
  DatabaseQualityOptions o;
  o.score = false;
  o.synthetic_views = 0;
  int calls = 0;
  o.assess = [&](const TargetInfo&, const cv::Mat&) {
    ++calls;
    return QualityReport{};
  };
  const DatabaseQualityReport r = AssessDatabase(db_, o);
  EXPECT_EQ(calls, 0);
  for (const auto& e : r.exhibits) EXPECT_FALSE(e.assessed);
  ASSERT_FALSE(r.pairs.empty());
  for (const auto& p : r.pairs) EXPECT_EQ(p.probes, 1);
}

TEST(DatabaseQualityErrors, NotADatabaseIsAClearError) {
  const fs::path f = fs::temp_directory_path() / "mvkp_db_quality_not_a_db.txt";
  std::ofstream(f) << "not a database\n";
  try {
    AssessDatabase(f.string());
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not an mvkp target database"), std::string::npos) << e.what();
  }
  fs::remove(f);
  EXPECT_THROW(AssessDatabase((fs::temp_directory_path() / "mvkp_no_such.db").string()), Error);
  DatabaseQualityOptions bad;
  bad.synthetic_views = -1;
  EXPECT_THROW(AssessDatabase(f.string(), bad), Error);
}

}  // namespace
}  // namespace mvkp
