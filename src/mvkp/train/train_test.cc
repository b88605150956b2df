#include "mvkp/train/trainer.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/synth/synth.h"
#include "mvkp/index/kmeans.h"

#include "test_samples.h"

namespace mvkp {
namespace {

using mvkp::testing::Sample;

TEST(KMeans, SeparatesWellSeparatedClustersDeterministically) {
  std::vector<float> pts;
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < 20; ++i) {
      pts.push_back(c * 100.f + float(i % 5));
      pts.push_back(-c * 50.f + float(i % 3));
    }
  std::vector<float> a, b;
  KMeans(pts.data(), 60, 2, 3, 20, 1, a);
  KMeans(pts.data(), 60, 2, 3, 20, 1, b);
  EXPECT_EQ(a, b);
  std::vector<float> xs = {a[0], a[2], a[4]};
  std::sort(xs.begin(), xs.end());
  EXPECT_NEAR(xs[0], 2.f, 0.5f);
  EXPECT_NEAR(xs[1], 102.f, 0.5f);
  EXPECT_NEAR(xs[2], 202.f, 0.5f);
  KMeans(pts.data(), 2, 2, 5, 10, 1, a);  // fewer points than centres
  EXPECT_EQ(a.size(), 4u);
}

TEST(Train, RifsReportRanksTracksByFinalScoreAndKeepsTheRequestedShare) {
  TrainOptions o;
  o.view_model = ViewModel::kAffine;  // the thesis's setting: one level of affine views
  o.views = 30;
  o.rotation_views = 36;
  o.select = Selection::kRifs;
  o.alpha = 0.5;
  o.keep_fraction = 0.3;
  TrainReport r;
  const Model m = Train(Sample("starry_night.jpg"), o, &r);
  EXPECT_EQ(r.general_views, 30);
  EXPECT_EQ(r.rotation_views, 36);
  EXPECT_EQ(r.min_stability, 3);  // max(3, 66 / 20)
  ASSERT_GT(r.eligible, 100);
  EXPECT_NEAR(r.kept, 0.3 * r.eligible, 0.01 * r.eligible + 1);  // 30 % of the tracks with a general view
  EXPECT_EQ(int(m.locations.size()), r.kept);
  int kept = 0, prev_rank = -1;
  double prev = 1e300;
  for (const auto& t : r.tracks) {
    if (t.rank < 0) {
      EXPECT_LT(t.score.ss, r.min_stability);
      EXPECT_FALSE(t.kept);
      continue;
    }
    EXPECT_EQ(t.rank, prev_rank + 1);
    prev_rank = t.rank;
    EXPECT_LE(t.score.frs, prev);
    prev = t.score.frs;
    EXPECT_LE(t.score.ss, 66);
    EXPECT_LE(t.general, 30);
    EXPECT_NEAR(t.score.frs, 0.5 * t.score.rrs_scaled + 0.5 * t.score.ss, 1e-9);
    EXPECT_GE(t.score.rrs_scaled, r.min_stability - 1e-9);
    EXPECT_LE(t.score.rrs_scaled, 66 + 1e-9);
    kept += t.kept;
  }
  EXPECT_EQ(kept, r.kept);
  // Stability selection: general views only, ranked by SS.
  o.select = Selection::kStability;
  o.keep_fraction = 0;
  o.locations = 50;
  TrainReport s;
  Train(Sample("starry_night.jpg"), o, &s);
  EXPECT_EQ(s.rotation_views, 0);
  EXPECT_EQ(s.kept, 50);
  for (std::size_t i = 1; i < s.tracks.size() && s.tracks[i].rank >= 0; ++i)
    EXPECT_GE(s.tracks[i - 1].score.ss, s.tracks[i].score.ss);
}

TEST(Train, RifsOptionsAreChecked) {
  TrainOptions o;
  o.alpha = -0.1;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.keep_fraction = 1.5;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.min_stability = o.views + o.rotation_views + 1;
  EXPECT_THROW(o.Check(), Error);
}

TEST(Train, ProducesAStableReproducibleModel) {
  const cv::Mat img = Sample("starry_night.jpg");
  TrainOptions o;
  o.view_model = ViewModel::kAffine;
  o.views = 40;
  o.locations = 100;
  o.clusters = 10;
  const Model m = Train(img, o);
  EXPECT_EQ(m.object_width, img.cols);
  EXPECT_EQ(int(m.locations.size()), 100);
  EXPECT_EQ(m.descriptors.cols, 20);
  EXPECT_LE(m.descriptors.rows, 100 * 10);
  EXPECT_GE(m.descriptors.rows, 100 * 5);
  for (std::size_t i = 1; i < m.locations.size(); ++i) EXPECT_GE(m.locations[i - 1].stability, m.locations[i].stability);
  EXPECT_GE(m.locations[0].stability, 20);  // the best location is seen in half the views or more
  for (const auto& l : m.locations) {
    EXPECT_GE(l.x, 0); EXPECT_LT(l.x, img.cols);
    EXPECT_GE(l.y, 0); EXPECT_LT(l.y, img.rows);
  }
  const Model again = Train(img, o);
  EXPECT_EQ(cv::norm(m.descriptors, again.descriptors, cv::NORM_INF), 0.0);
  o.seed = 7;
  const Model other = Train(img, o);
  EXPECT_TRUE(other.descriptors.rows != m.descriptors.rows ||
              cv::norm(m.descriptors, other.descriptors, cv::NORM_INF) > 0.0);
}

TEST(Train, LocationsAreRealCornersOfTheObject) {
  // A synthetic object whose corners we know: bright squares on a dark page.
  cv::Mat img(240, 320, CV_8UC1, cv::Scalar(30));
  std::vector<cv::Point> corners;
  for (int y = 40; y < 200; y += 60)
    for (int x = 40; x < 280; x += 60) {
      cv::rectangle(img, cv::Rect(x, y, 30, 30), cv::Scalar(220), -1);
      for (auto c : {cv::Point(x, y), cv::Point(x + 29, y), cv::Point(x, y + 29), cv::Point(x + 29, y + 29)}) corners.push_back(c);
    }
  TrainOptions o;
  o.views = 40;
  o.locations = 30;
  o.clusters = 5;
  const Model m = Train(img, o);  // every level's locations, in input pixels
  ASSERT_GT(m.params.levels, 1);
  // Within 3 pixels of its level (a level at 1/4 size blurs the squares).
  int near = 0, fine = 0;
  for (const auto& l : m.locations) {
    if (l.scale > 2.5f) continue;  // levels coarser than half size: the 30 px squares are blobs there
    ++fine;
    float best = 1e9f;
    for (auto c : corners) best = std::min(best, std::hypot(l.x - c.x, l.y - c.y));
    near += best < 3.0 * l.scale;
  }
  EXPECT_GE(fine, 30);
  EXPECT_GE(near, int(fine * 0.9));
}

TEST(Train, RefusesATargetWithoutTexture) {
  cv::Mat flat(200, 300, CV_8UC1, cv::Scalar(120));
  cv::rectangle(flat, cv::Rect(100, 80, 60, 40), cv::Scalar(130), -1);  // one faint box: 4 corners
  try {
    Train(flat, {});
    FAIL() << "trained on a flat image";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kNoTexture);
    EXPECT_NE(std::string(e.what()).find("too little texture"), std::string::npos);
  }
}

TEST(Train, RejectsBadOptions) {
  TrainOptions o;
  o.views = 0;
  EXPECT_THROW(Train(Sample("coffee.jpg"), o), Error);
}

}  // namespace
}  // namespace mvkp
