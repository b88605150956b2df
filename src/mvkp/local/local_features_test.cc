#include "mvkp/local/local_features.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/local/pair_match.h"

#include "test_samples.h"

namespace mvkp {
namespace {

using mvkp::testing::Sample;

// The image rotated by 25 degrees and scaled by 0.8 about its centre, with the homography.
std::pair<cv::Mat, cv::Matx33d> Warped(const cv::Mat& img) {
  const cv::Mat A = cv::getRotationMatrix2D(cv::Point2f(img.cols / 2.f, img.rows / 2.f), 25, 0.8);
  cv::Mat out;
  cv::warpAffine(img, out, A, img.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Matx33d H = cv::Matx33d::eye();
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) H(r, c) = A.at<double>(r, c);
  return {out, H};
}

double CornerError(const cv::Matx33d& a, const cv::Matx33d& b, cv::Size s) {
  double e = 0;
  for (cv::Point2d p : {cv::Point2d(0, 0), cv::Point2d(s.width, 0), cv::Point2d(s.width, s.height), cv::Point2d(0, s.height)}) {
    const cv::Vec3d u = a * cv::Vec3d(p.x, p.y, 1), v = b * cv::Vec3d(p.x, p.y, 1);
    e += std::hypot(u[0] / u[2] - v[0] / v[2], u[1] / u[2] - v[1] / v[2]);
  }
  return e / 4;
}

TEST(LocalFeatures, EveryMethodRecoversAKnownHomography) {
  const cv::Mat img = Sample("starry_night.jpg");
  const auto [view, H] = Warped(img);
  for (const auto& name : LocalFeatureMethodNames()) {
    SCOPED_TRACE(name);
    const auto m = LocalFeatureMethod::Create(name);
    EXPECT_EQ(m->name(), name);
    const LocalFeatures a = m->Extract(img), b = m->Extract(view);
    ASSERT_GT(a.keypoints.size(), 100u);
    EXPECT_EQ(a.descriptors.rows, int(a.keypoints.size()));
    EXPECT_EQ(name.rfind("aug-", 0) == 0, !a.codes.empty());
    if (!a.codes.empty()) {
      EXPECT_EQ(a.codes.rows, int(a.keypoints.size()));
    }
    EXPECT_GE(a.detect_ms, 0);
    EXPECT_GT(m->descriptor_bytes(), 0);
    const auto nearest = m->Match(a, b);
    EXPECT_EQ(nearest.size(), b.keypoints.size());
    const PairMatchResult r = MatchPair(a, b, nearest);
    ASSERT_TRUE(r.found);
    EXPECT_LT(CornerError(r.homography, H, img.size()), 3.0);
    // The ratio sweep: monotone, correct <= matches <= keypoints, recall <= 1.
    const PairEvaluation e = EvaluatePair(a, b, nearest, H, view.size(), DefaultRatioSweep());
    ASSERT_EQ(e.sweep.size(), 10u);
    EXPECT_GT(e.correspondences, 50);
    for (std::size_t i = 0; i < e.sweep.size(); ++i) {
      EXPECT_LE(e.sweep[i].correct, e.sweep[i].matches);
      EXPECT_LE(e.sweep[i].correct, e.correspondences + int(b.keypoints.size()));
      if (i) {
        EXPECT_GE(e.sweep[i].matches, e.sweep[i - 1].matches);
        EXPECT_GE(e.sweep[i].correct, e.sweep[i - 1].correct);
      }
    }
    EXPECT_GT(e.sweep[6].correct, 30);  // ratio 0.8
  }
}

TEST(LocalFeatures, DescriptorBytes) {
  EXPECT_EQ(LocalFeatureMethod::Create("cdikp")->descriptor_bytes(), 80);   // 20 floats
  EXPECT_EQ(LocalFeatureMethod::Create("sift")->descriptor_bytes(), 512);   // 128 floats
  EXPECT_EQ(LocalFeatureMethod::Create("orb")->descriptor_bytes(), 32);
  EXPECT_EQ(LocalFeatureMethod::Create("aug-cdikp")->descriptor_bytes(), 20);  // 20 one-byte ranks
}

TEST(PairMatch, EvaluationCountsByHand) {
  LocalFeatures obj, qry;
  obj.keypoints = {cv::KeyPoint(10, 10, 5), cv::KeyPoint(50, 50, 5), cv::KeyPoint(500, 500, 5)};  // the last maps outside
  qry.keypoints = {cv::KeyPoint(11, 10, 5), cv::KeyPoint(80, 80, 5)};
  // Query 0 -> object 0 (correct, ratio 0.5); query 1 -> object 1 (wrong, ratio 0.9).
  const std::vector<NearestTwo> nn = {{0, 0, 1, 1.f, 2.f}, {1, 1, 0, 0.9f, 1.f}};
  const PairEvaluation e = EvaluatePair(obj, qry, nn, cv::Matx33d::eye(), cv::Size(100, 100), {0.6, 0.95}, 3.0);
  EXPECT_EQ(e.correspondences, 1);  // object 0 has query 0 within 3 px; object 1 has none; object 2 is outside
  ASSERT_EQ(e.sweep.size(), 2u);
  EXPECT_EQ(e.sweep[0].matches, 1);
  EXPECT_EQ(e.sweep[0].correct, 1);
  EXPECT_EQ(e.sweep[1].matches, 2);
  EXPECT_EQ(e.sweep[1].correct, 1);
}

TEST(LocalFeatures, BadInput) {
  EXPECT_THROW(LocalFeatureMethod::Create("surf"), Error);
  const auto m = LocalFeatureMethod::Create("cdikp");
  EXPECT_THROW(m->Extract(cv::Mat()), Error);
  const LocalFeatures flat = m->Extract(cv::Mat(200, 200, CV_8UC1, cv::Scalar(90)));
  EXPECT_TRUE(flat.keypoints.empty());
  EXPECT_TRUE(m->Match(flat, flat).empty());
  // Mismatched descriptor types (float CDIKP against binary ORB).
  const cv::Mat img = Sample("coffee.jpg");
  const LocalFeatures c = m->Extract(img), o = LocalFeatureMethod::Create("orb")->Extract(img);
  EXPECT_THROW(m->Match(c, o), Error);
  PairMatchOptions po;
  po.ratio = 0;
  EXPECT_THROW(MatchPair(c, c, {}, po), Error);
}

}  // namespace
}  // namespace mvkp
