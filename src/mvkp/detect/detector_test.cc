#include "mvkp/detect/detector.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace mvkp {
namespace {

cv::Mat Checker(int w, int h, int cell) {
  cv::Mat img(h, w, CV_8UC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.at<std::uint8_t>(y, x) = ((x / cell + y / cell) % 2) ? 200 : 50;
  cv::GaussianBlur(img, img, cv::Size(), 1.0);
  return img;
}

TEST(Detector, FindsCheckerboardCornersAndRespectsLimits) {
  const cv::Mat img = Checker(200, 160, 20);
  DetectorOptions o;
  o.max_points = 1000;
  const auto kps = DetectMinEigen(img, o);
  // Interior corners at multiples of 20 (excluding the border band).
  int near_corner = 0;
  for (const auto& k : kps) {
    const float dx = std::abs(k.x - std::round(k.x / 20) * 20), dy = std::abs(k.y - std::round(k.y / 20) * 20);
    near_corner += dx <= 1.5f && dy <= 1.5f;
  }
  EXPECT_GE(near_corner, 40);
  EXPECT_GE(double(near_corner) / kps.size(), 0.9);
  // Strongest first, spacing respected, border respected.
  for (std::size_t i = 1; i < kps.size(); ++i) EXPECT_GE(kps[i - 1].strength, kps[i].strength);
  for (std::size_t i = 0; i < kps.size(); ++i) {
    EXPECT_GE(kps[i].x, o.border);
    EXPECT_LT(kps[i].x, img.cols - o.border);
    for (std::size_t j = i + 1; j < kps.size(); ++j)
      EXPECT_GE(std::hypot(kps[i].x - kps[j].x, kps[i].y - kps[j].y), o.min_distance);
  }
  o.max_points = 10;
  EXPECT_EQ(DetectMinEigen(img, o).size(), 10u);
}

TEST(MinEigen, EqualsOpenCVAwayFromTheBorder) {
  cv::Mat img(97, 131, CV_8UC1);
  cv::RNG(4).fill(img, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(img, img, cv::Size(), 1.0);
  cv::Mat ours, ref;
  MinEigen3x3(img, ours);
  cv::cornerMinEigenVal(img, ref, 3, 3);
  double maxv;
  cv::minMaxLoc(ref, nullptr, &maxv);
  const cv::Rect inner(2, 2, img.cols - 4, img.rows - 4);
  EXPECT_LT(cv::norm(ours(inner), ref(inner), cv::NORM_INF), 1e-4 * maxv);
}

TEST(Detector, FlatImageHasNoPoints) {
  cv::Mat flat(120, 120, CV_8UC1, cv::Scalar(128));
  EXPECT_TRUE(DetectMinEigen(flat, {}).empty());
  cv::Mat noisy(120, 120, CV_8UC1);
  cv::RNG(1).fill(noisy, cv::RNG::NORMAL, 128, 0.6);
  cv::GaussianBlur(noisy, noisy, cv::Size(), 1.0);
  EXPECT_LT(DetectMinEigen(noisy, {}).size(), 5u);  // sensor-level noise is below the absolute threshold
}

TEST(Detector, MaskRestrictsDetections) {
  const cv::Mat img = Checker(200, 160, 20);
  cv::Mat mask = cv::Mat::zeros(img.size(), CV_8UC1);
  mask(cv::Rect(0, 0, 100, 160)).setTo(255);
  for (const auto& k : DetectMinEigen(img, {}, mask)) EXPECT_LT(k.x, 100);
}

}  // namespace
}  // namespace mvkp
