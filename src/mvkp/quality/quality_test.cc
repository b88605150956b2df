#include "mvkp/quality/quality.h"

#include <algorithm>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

#include "test_samples.h"

namespace mvkp {
namespace {

using mvkp::testing::Sample;

QualityOptions Fast() {
  QualityOptions o;
  o.test_views = 16;
  return o;
}

bool HasReason(const QualityReport& r, const std::string& code) {
  return std::any_of(r.reasons.begin(), r.reasons.end(), [&](const QualityReason& q) { return q.code == code; });
}

double Factor(const QualityReport& r, const std::string& name) {
  for (const auto& f : r.factors)
    if (f.name == name) return f.factor;
  ADD_FAILURE() << "no factor " << name;
  return -1;
}

TEST(Quality, TexturedPaintingScoresHighAndIsDetected) {
  const QualityReport r = AssessTarget(Sample("starry_night.jpg"), Fast());
  EXPECT_GE(r.score, 70);
  EXPECT_GE(r.detection_rate, 0.75);
  EXPECT_GT(r.eligible_tracks, 200);
  EXPECT_EQ(int(r.selected.size()), r.selected_tracks);
  // The factor points add up to the score, and points + lost to 100.
  double total = 0, lost = 0;
  for (const auto& f : r.factors) {
    total += f.points;
    lost += f.lost;
  }
  EXPECT_NEAR(total, r.score, 0.5 + 1e-9);
  EXPECT_NEAR(total + lost, 100.0, 1e-6);
  EXPECT_FALSE(HasReason(r, "uniform"));
}

TEST(Quality, TiledPatternIsReportedAsRepeated) {
  // One 48x48 textured motif tiled 8x6: every point has look-alikes.
  const cv::Mat src = Sample("baboon.jpg");
  const cv::Mat motif = src(cv::Rect(200, 200, 48, 48)).clone();
  cv::Mat tiled;
  cv::repeat(motif, 6, 8, tiled);
  const QualityReport tiles = AssessTarget(tiled, Fast());
  const QualityReport painting = AssessTarget(Sample("starry_night.jpg"), Fast());
  EXPECT_TRUE(HasReason(tiles, "repeated_elements"));
  EXPECT_LT(Factor(tiles, "distinctiveness"), 0.5);
  EXPECT_GT(Factor(painting, "distinctiveness"), 0.9);
  EXPECT_LT(tiles.score, painting.score - 20);
  double total = 0, lost = 0;
  for (const auto& f : tiles.factors) {
    total += f.points;
    lost += f.lost;
  }
  EXPECT_NEAR(total + lost, 100.0, 1e-6);
}

TEST(Quality, SmallLogoOnPlainCanvasIsConcentrated) {
  // The textured part fills only one corner of the canvas.
  cv::Mat canvas(480, 640, CV_8UC1, cv::Scalar(235));
  cv::Mat patch;
  cv::resize(Sample("starry_night.jpg"), patch, cv::Size(160, 128));
  patch.copyTo(canvas(cv::Rect(20, 20, 160, 128)));
  const QualityReport r = AssessTarget(canvas, Fast());
  EXPECT_TRUE(HasReason(r, "concentrated"));
  EXPECT_TRUE(HasReason(r, "low_texture"));
  EXPECT_LT(Factor(r, "coverage"), 0.5);
}

TEST(Quality, UniformTinyAndTexturelessImagesScoreZeroWithAReason) {
  const QualityReport flat = AssessTarget(cv::Mat(300, 400, CV_8UC1, cv::Scalar(128)), Fast());
  EXPECT_EQ(flat.score, 0);
  ASSERT_FALSE(flat.reasons.empty());
  EXPECT_EQ(flat.reasons[0].code, "uniform");
  cv::Mat noisy(300, 400, CV_8UC1);
  cv::randn(noisy, 128, 1.5);
  EXPECT_EQ(AssessTarget(noisy, Fast()).reasons.at(0).code, "uniform");
  const QualityReport tiny = AssessTarget(Sample("starry_night.jpg")(cv::Rect(0, 0, 20, 20)).clone(), Fast());
  EXPECT_EQ(tiny.score, 0);
  EXPECT_EQ(tiny.reasons.at(0).code, "too_small");
  cv::Mat ramp(300, 400, CV_8UC1);
  for (int y = 0; y < ramp.rows; ++y)
    for (int x = 0; x < ramp.cols; ++x) ramp.at<std::uint8_t>(y, x) = std::uint8_t(x * 255 / ramp.cols);
  const QualityReport r = AssessTarget(ramp, Fast());
  EXPECT_LE(r.score, 10);
  EXPECT_TRUE(HasReason(r, "few_stable_points"));
  EXPECT_EQ(r.detection_rate, 0);
}

TEST(Quality, StableUnderBrightnessAndSizeButNotContrast) {
  const cv::Mat img = Sample("fruits.jpg");
  const QualityReport base = AssessTarget(img, Fast());
  cv::Mat bright, big, faint;
  img.convertTo(bright, CV_8U, 1.0, 25);
  cv::resize(img, big, cv::Size(), 2.0, 2.0, cv::INTER_CUBIC);
  EXPECT_LE(std::abs(AssessTarget(bright, Fast()).score - base.score), 10);
  EXPECT_LE(std::abs(AssessTarget(big, Fast()).score - base.score), 10);
  // The score measures the image as given (issue 18): a copy at a quarter of
  // the contrast is found less often in practice, and the score says so.
  img.convertTo(faint, CV_8U, 0.25, 96);
  const QualityReport f = AssessTarget(faint, Fast());
  EXPECT_LT(f.detection_rate, base.detection_rate);
  EXPECT_LT(f.score, base.score);
}

const QualityReason* Reason(const QualityReport& r, const std::string& code) {
  for (const auto& q : r.reasons)
    if (q.code == code) return &q;
  return nullptr;
}

// Issue 20: the low-detection reason said "below 30 % the other factors count
// only in part" at 68 % detection. It now states the measured rate, and the
// 30 % clause only when the rate is below it.
TEST(Quality, LowDetectionWordingFollowsTheMeasuredRate) {
  const QualityReport found = AssessTarget(Sample("starry_night.jpg"), Fast());
  const QualityReason* q = Reason(found, "low_detection");
  ASSERT_NE(q, nullptr) << "found in " << found.detection_rate << " of the views";
  ASSERT_GE(found.factors.at(0).factor, 0.3);
  char pct[16];
  std::snprintf(pct, sizeof pct, "in %.0f%%", 100 * found.detection_rate);
  EXPECT_NE(q->message.find(pct), std::string::npos) << q->message;
  EXPECT_EQ(q->message.find("below"), std::string::npos) << q->message;
  EXPECT_EQ(q->message.find("count only in part"), std::string::npos) << q->message;

  // A tiled motif is rarely found: there the clause applies and says so.
  cv::Mat tiled;
  cv::repeat(Sample("baboon.jpg")(cv::Rect(200, 200, 48, 48)).clone(), 6, 8, tiled);
  const QualityReport tiles = AssessTarget(tiled, Fast());
  ASSERT_LT(tiles.factors.at(0).factor, 0.3);
  const QualityReason* t = Reason(tiles, "low_detection");
  ASSERT_NE(t, nullptr);
  EXPECT_NE(t->message.find("below 30%"), std::string::npos) << t->message;
}

// Issue 20: quality reported 17 stable points where `mvkp db add` refused the
// image for 7: quality trained at 640 px, the database at 320. Both now name
// the size, and at the same size they count the same tracks.
TEST(Quality, StablePointsNameTheTrainingSizeAndMatchTheTrainer) {
  cv::Mat img(480, 640, CV_8UC1, cv::Scalar(200));
  cv::rectangle(img, cv::Rect(100, 80, 200, 150), cv::Scalar(40), cv::FILLED);
  cv::circle(img, cv::Point(450, 300), 90, cv::Scalar(90), cv::FILLED);
  cv::line(img, cv::Point(50, 420), cv::Point(600, 380), cv::Scalar(0), 6);
  const QualityReport at640 = AssessTarget(img, Fast());
  EXPECT_EQ(at640.train_side, 640);
  const QualityReason* q = Reason(at640, "few_stable_points");
  ASSERT_NE(q, nullptr);
  EXPECT_NE(q->message.find(std::to_string(at640.eligible_tracks) + " stable points when trained at 640 px"),
            std::string::npos)
      << q->message;

  QualityOptions db = Fast();
  db.train.max_object_side = 320;  // as `mvkp db add` trains (RecognitionTrainDefaults)
  TrainOptions t = db.train;
  TrainReport tr;
  int trainer_count = -1;
  try {
    Train(img, t, &tr);
    trainer_count = int(std::count_if(tr.tracks.begin(), tr.tracks.end(),
                                      [](const TrackReport& k) { return k.level == 0 && k.rank >= 0; }));
  } catch (const Error& e) {
    // The refusal names the count and the size.
    const std::string m = e.what();
    ASSERT_NE(m.find("when trained at 320 px"), std::string::npos) << m;
    trainer_count = std::stoi(m.substr(m.find("train: ") + 7));
  }
  const QualityReport at320 = AssessTarget(img, db);
  if (at320.train_side > 0) {
    EXPECT_EQ(at320.train_side, 320);
    EXPECT_EQ(at320.eligible_tracks, trainer_count);
  }
  EXPECT_LT(trainer_count, at640.eligible_tracks);
}

TEST(Quality, DrawingMarksSelectedFeatures) {
  const cv::Mat img = Sample("coffee.jpg");
  const QualityReport r = AssessTarget(img, Fast());
  ASSERT_FALSE(r.selected.empty());
  const cv::Mat d = DrawQuality(img, r);
  EXPECT_EQ(d.size(), img.size());
  EXPECT_EQ(d.type(), CV_8UC3);
  const cv::Point p(int(std::lround(r.selected[0].x)), int(std::lround(r.selected[0].y)));
  const cv::Vec3b c = d.at<cv::Vec3b>(p);  // white plus (anti-aliased)
  EXPECT_GE(std::min({c[0], c[1], c[2]}), 240);
}

TEST(Quality, RejectsBadArguments) {
  EXPECT_THROW(AssessTarget(cv::Mat(), Fast()), Error);
  EXPECT_THROW(AssessTarget(cv::Mat(100, 100, CV_32F, cv::Scalar(0)), Fast()), Error);
  QualityOptions o = Fast();
  o.w_detection = 0.9;
  EXPECT_THROW(AssessTarget(Sample("coffee.jpg"), o), Error);
  o = Fast();
  o.test_views = 0;
  EXPECT_THROW(AssessTarget(Sample("coffee.jpg"), o), Error);
}

}  // namespace
}  // namespace mvkp
