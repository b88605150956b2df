#include "mvkp/synth/synth.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace mvkp {
namespace {

TEST(AffineViews, CoverTheThesisRangesReproducibly) {
  ViewSamplerOptions o;
  const auto a = SampleAffineViews(100, o), b = SampleAffineViews(100, o);
  double tmin = 9, tmax = -9, lmin = 9, lmax = -9;
  for (int i = 0; i < 100; ++i) {
    EXPECT_EQ(a[i].theta, b[i].theta);
    tmin = std::min(tmin, a[i].theta); tmax = std::max(tmax, a[i].theta);
    lmin = std::min({lmin, a[i].lambda1, a[i].lambda2}); lmax = std::max({lmax, a[i].lambda1, a[i].lambda2});
    EXPECT_GE(a[i].phi, -CV_PI / 2); EXPECT_LE(a[i].phi, CV_PI / 2);
    EXPECT_GE(a[i].t1, 0); EXPECT_LE(a[i].t1, 3);
  }
  EXPECT_LT(tmin, -CV_PI * 0.9); EXPECT_GT(tmax, CV_PI * 0.9);
  EXPECT_LT(lmin, 0.45); EXPECT_GT(lmax, 1.55);
  o.seed = 43;
  EXPECT_NE(SampleAffineViews(1, o)[0].theta, a[0].theta);
}

TEST(AffineMatrix, IsRotationTimesSymmetricScaling) {
  AffineParams p{0.3, 0.7, 0.5, 1.5, 0, 0};
  const cv::Matx22d A = AffineMatrix(p);
  EXPECT_NEAR(cv::determinant(A), 0.75, 1e-12);
}

TEST(SceneView, HomographyPutsTheTargetWhereItSays) {
  cv::Mat target(120, 160, CV_8UC1, cv::Scalar(0));
  cv::circle(target, {40, 30}, 6, cv::Scalar(255), -1);  // a bright dot to find again
  SceneOptions o;
  o.clutter = false;
  o.lighting = false;
  o.max_noise = 0;
  o.max_blur = 0;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const SceneView v = MakeSceneView(target, o, seed);
    const auto v2 = MakeSceneView(target, o, seed);
    EXPECT_EQ(cv::norm(v.image, v2.image, cv::NORM_INF), 0.0);  // reproducible
    std::vector<cv::Point2d> p{{40, 30}}, q;
    cv::perspectiveTransform(p, q, cv::Mat(v.H));
    if (q[0].x < 5 || q[0].y < 5 || q[0].x > o.width - 5 || q[0].y > o.height - 5) continue;
    EXPECT_GT(v.image.at<std::uint8_t>(int(std::lround(q[0].y)), int(std::lround(q[0].x))), 150) << seed;
  }
}

}  // namespace
}  // namespace mvkp
