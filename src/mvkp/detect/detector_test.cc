#include "mvkp/detect/detector.h"

#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/detect/internal/detect_kernels.h"

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

namespace mvkp {
namespace {

// Dots of contrast `c` on grey over the rectangle r.
void Dots(cv::Mat& img, cv::Rect r, int contrast, std::uint64_t seed) {
  cv::RNG rng(seed);
  for (int i = 0; i < r.area() / 150; ++i) {
    const cv::Point p(r.x + rng.uniform(0, r.width), r.y + rng.uniform(0, r.height));
    cv::rectangle(img, p, p + cv::Point(rng.uniform(2, 6), rng.uniform(2, 6)), cv::Scalar(128 + contrast), -1);
  }
}

TEST(Detector, GridQuotaGivesALowContrastRegionItsShare) {
  // A busy high-contrast frame with a small low-contrast patch (a dim
  // painting in a bright street): the N strongest all land in the busy part.
  cv::Mat img(480, 640, CV_8UC1, cv::Scalar(128));
  Dots(img, cv::Rect(0, 0, 640, 480), 110, 1);
  const cv::Rect dim(400, 240, 160, 120);  // 12 of the 16 x 12 cells of 40 px
  img(dim).setTo(128);
  Dots(img, dim, 12, 2);
  cv::GaussianBlur(img, img, cv::Size(), 1.0);
  auto on = [&](const std::vector<Keypoint>& kps) {
    int n = 0;
    for (const auto& k : kps) n += dim.contains(cv::Point(int(k.x), int(k.y)));
    return n;
  };
  DetectorOptions o;
  o.max_points = 500;
  o.grid_share = 0;
  const int strongest = on(DetectMinEigen(img, o));
  o.grid_share = 0.75f;
  o.grid_cells = 16;
  const auto spread = DetectMinEigen(img, o);
  EXPECT_LE(spread.size(), 500u);
  EXPECT_LT(strongest, 5);
  EXPECT_GE(on(spread), 15);  // about its cells' share of the quota (2 each)
  for (std::size_t i = 1; i < spread.size(); ++i) EXPECT_GE(spread[i - 1].strength, spread[i].strength);
}

TEST(DetectKernels, Avx2EqualsScalar) {
  if (internal::BestNmsRow() == internal::NmsRowScalar) GTEST_SKIP() << "no AVX2 on this CPU";
  cv::Mat img(53, 203, CV_8UC1);
  cv::RNG(9).fill(img, cv::RNG::UNIFORM, 0, 256);
  const int W = img.cols;
  std::vector<float> a(W), b(W), c(W), d(W), e(W), f(W), g(W), h(W), i(W), j(W), k(W), l(W);
  internal::GradientRowScalar(img.ptr(10), img.ptr(11), img.ptr(12), W, a.data(), b.data(), c.data(), d.data(),
                              e.data(), f.data());
  internal::GradientRowAvx2(img.ptr(10), img.ptr(11), img.ptr(12), W, g.data(), h.data(), i.data(), j.data(), k.data(),
                            l.data());
  for (int x = 2; x < W - 2; ++x) {
    EXPECT_EQ(d[x], j[x]);
    EXPECT_EQ(e[x], k[x]);
    EXPECT_EQ(f[x], l[x]);
  }
  std::vector<float> o1(W), o2(W);
  internal::EigenRowScalar(d.data(), j.data(), d.data(), e.data(), k.data(), e.data(), f.data(), l.data(), f.data(), 2,
                           W - 2, 1e-6f, o1.data());
  internal::EigenRowAvx2(d.data(), j.data(), d.data(), e.data(), k.data(), e.data(), f.data(), l.data(), f.data(), 2,
                         W - 2, 1e-6f, o2.data());
  for (int x = 2; x < W - 2; ++x) EXPECT_EQ(o1[x], o2[x]);
  cv::Mat eig;
  cv::Mat s;
  cv::GaussianBlur(img, s, cv::Size(), 1.0);
  MinEigen3x3(s, eig);
  for (int y = 1; y < eig.rows - 1; ++y) {
    std::vector<int> p, q;
    internal::NmsRowScalar(eig.ptr<float>(y - 1), eig.ptr<float>(y), eig.ptr<float>(y + 1), 1, W - 1, 1e-5f, p);
    internal::NmsRowAvx2(eig.ptr<float>(y - 1), eig.ptr<float>(y), eig.ptr<float>(y + 1), 1, W - 1, 1e-5f, q);
    EXPECT_EQ(p, q) << "row " << y;
  }
  // Row maxima (per-cell thresholds), with and without a mask, over spans
  // shorter and longer than a vector, against the scalar loop and cv::minMaxLoc.
  cv::Mat mask(eig.size(), CV_8UC1);
  cv::RNG(5).fill(mask, cv::RNG::UNIFORM, 0, 2);
  for (int y = 0; y < eig.rows; y += 7)
    for (const auto& [x0, x1] : std::vector<std::pair<int, int>>{{0, W}, {3, 11}, {5, 40}, {17, 18}, {9, 9}, {1, W - 2}}) {
      const float* row = eig.ptr<float>(y);
      const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
      EXPECT_EQ(internal::RowMaxAvx2(row, nullptr, x0, x1, 0.f), internal::RowMaxScalar(row, nullptr, x0, x1, 0.f));
      EXPECT_EQ(internal::RowMaxAvx2(row, m, x0, x1, -1.f), internal::RowMaxScalar(row, m, x0, x1, -1.f));
      if (x1 > x0) {
        double mx = 0;
        cv::minMaxLoc(eig.row(y).colRange(x0, x1), nullptr, &mx);
        EXPECT_EQ(internal::RowMaxAvx2(row, nullptr, x0, x1, -1.f), float(mx)) << y << " " << x0 << ".." << x1;
      }
    }
}

}  // namespace
}  // namespace mvkp
