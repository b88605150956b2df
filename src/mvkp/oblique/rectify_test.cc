#include "mvkp/oblique/rectify.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

// An upright camera `tilt_deg` off nadir looking north-east, 300 m up.
cv::Matx34d Camera(const cv::Matx33d& K, double tilt_deg) {
  const double a = tilt_deg * CV_PI / 180, az = 0.8;
  // look = horizontal heading h tilted down; right = h x up
  const cv::Vec3d h(std::sin(az), std::cos(az), 0), up(0, 0, 1);
  const cv::Vec3d look = std::sin(a) * h - std::cos(a) * up, right = h.cross(up), down = look.cross(right);
  const cv::Matx33d R(right[0], right[1], right[2], down[0], down[1], down[2], look[0], look[1], look[2]);
  const cv::Vec3d t = -(R * cv::Vec3d(0, 0, 300));
  cv::Matx34d P;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) P(i, j) = R(i, j);
    P(i, 3) = t[i];
  }
  return K * P;
}

// Ground points seen by the view, and where the rectification puts them;
// the RMS residual of the similarity between the ground (metres east and
// south, as depth pixels run) and rectified pixels.
double SimilarityResidual(const cv::Matx33d& K, cv::Size size, double true_tilt, double tilt) {
  const cv::Matx34d P = Camera(K, true_tilt);
  const Rectification r = RectifyForTilt(size, K, tilt);
  std::vector<cv::Point2f> ground, rect;
  for (double x = -400; x <= 400; x += 20)
    for (double y = -100; y <= 900; y += 20) {
      const cv::Vec3d u = P * cv::Vec4d(x, y, 0, 1);
      if (!(u[2] > 0)) continue;
      const double px = u[0] / u[2], py = u[1] / u[2];
      if (px < 0 || py < 0 || px > size.width - 1 || py > size.height - 1) continue;
      const cv::Vec3d q = r.H * cv::Vec3d(px, py, 1);
      ground.emplace_back(float(x), float(-y));  // depth pixels: rows run south
      rect.emplace_back(float(q[0] / q[2]), float(q[1] / q[2]));
    }
  EXPECT_GT(ground.size(), 50u);
  std::vector<uchar> mask;
  const cv::Mat A = cv::estimateAffinePartial2D(ground, rect, mask, cv::LMEDS);
  EXPECT_FALSE(A.empty());
  double ss = 0;
  for (std::size_t i = 0; i < ground.size(); ++i) {
    const double ex = A.at<double>(0, 0) * ground[i].x + A.at<double>(0, 1) * ground[i].y + A.at<double>(0, 2) - rect[i].x;
    const double ey = A.at<double>(1, 0) * ground[i].x + A.at<double>(1, 1) * ground[i].y + A.at<double>(1, 2) - rect[i].y;
    ss += ex * ex + ey * ey;
  }
  return std::sqrt(ss / double(ground.size()));
}

// At the right tilt the ground of the rectified view is a similarity of
// the ground (a mirror-free one: what shape contexts match); 10 degrees
// off, perspective is left over.
TEST(Rectify, TheGroundBecomesASimilarity) {
  const cv::Size size(1024, 768);
  const cv::Matx33d K(1098, 0, 511.5, 0, 1098, 383.5, 0, 0, 1);
  for (double tilt : {35.0, 50.0}) {
    EXPECT_LT(SimilarityResidual(K, size, tilt, tilt), 0.05) << tilt;
    EXPECT_GT(SimilarityResidual(K, size, tilt, tilt + 10), 2.0) << tilt;
  }
  const Rectification r = RectifyForTilt(size, K, 45);
  EXPECT_LE(std::max(r.size.width, r.size.height), RectifyOptions{}.max_side);
  EXPECT_GT(std::min(r.size.width, r.size.height), 300);
  EXPECT_GT(cv::determinant(r.H), 0);  // no mirror
  // the image centre stays in the rectified view
  const cv::Vec3d c = r.H * cv::Vec3d(511.5, 383.5, 1);
  EXPECT_GT(c[0] / c[2], 0);
  EXPECT_LT(c[0] / c[2], r.size.width);
  EXPECT_GT(c[1] / c[2], 0);
  EXPECT_LT(c[1] / c[2], r.size.height);
  const cv::Mat warped = Rectify(cv::Mat(size, CV_8UC3, cv::Scalar(40, 90, 200)), r);
  EXPECT_EQ(warped.size(), r.size);
}

TEST(Rectify, RefusesBadInput) {
  const cv::Matx33d K(1000, 0, 500, 0, 1000, 400, 0, 0, 1);
  EXPECT_THROW(RectifyForTilt({0, 0}, K, 40), Error);
  EXPECT_THROW(RectifyForTilt({1000, 800}, K, 95), Error);
  EXPECT_THROW(RectifyForTilt({1000, 800}, K, -1), Error);
  EXPECT_THROW(RectifyForTilt({1000, 800}, cv::Matx33d::zeros(), 40), Error);
  RectifyOptions o;
  o.max_side = 10;
  EXPECT_THROW(RectifyForTilt({1000, 800}, K, 40, o), Error);
  EXPECT_THROW(Rectify(cv::Mat(), RectifyForTilt({1000, 800}, K, 40)), Error);
}

}  // namespace
}  // namespace mvkp
