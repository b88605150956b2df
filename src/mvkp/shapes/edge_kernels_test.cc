// The AVX2 kernels of the shapes library (outline on edge, shape-context
// shift sums) must equal their scalar references bit for bit: the
// registration's answers may not depend on the CPU.
#include "mvkp/shapes/internal/edge_kernels.h"
#include "mvkp/shapes/internal/shift_kernels.h"

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/internal/cpu.h"

namespace mvkp::internal {
namespace {

TEST(EdgeKernels, Avx2EqualsScalarBitForBit) {
  if (!CpuHasAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(20261206);
  std::uniform_real_distribution<double> U(0, 1);
  // a smooth-ish photo with edges, not a multiple of 8 wide, with a row step larger than its width
  cv::Mat1f big(211, 300);
  cv::randu(big, 0, 255);
  cv::GaussianBlur(big, big, cv::Size(), 1.5);
  cv::rectangle(big, cv::Rect(40, 50, 90, 70), cv::Scalar(250), cv::FILLED);
  const cv::Mat1f img = big(cv::Rect(3, 0, 277, 211));
  int scored = 0, total = 0, windows = 0;
  for (int trial = 0; trial < 400; ++trial) {
    EdgeTapArgs a;
    a.image = img.ptr<float>(0);
    a.step = std::ptrdiff_t(img.step1());
    a.width = float(img.cols), a.height = float(img.rows);
    // depth -> photo: rotation, scale 0.2-6 (some too coarse or beyond k = 100 in the last trials), shift, perspective
    const double ang = 6.3 * U(rng), sc = trial % 50 == 49 ? 150.0 : 0.2 + 5.8 * U(rng);
    const double p0 = (U(rng) - 0.5) * 2e-3, p1 = (U(rng) - 0.5) * 2e-3;
    const double D[9] = {sc * std::cos(ang), -sc * std::sin(ang), 280 * U(rng) - 40,
                         sc * std::sin(ang), sc * std::cos(ang),  220 * U(rng) - 40,
                         p0, p1, 1};
    std::copy(D, D + 9, a.D);
    if (trial % 97 == 3) a.D[8] = 0;  // a degenerate map: w near 0 for some points
    if (trial % 101 == 5) a.D[0] = std::nan("");
    a.lean_x = (U(rng) - 0.5) * 0.6, a.lean_y = (U(rng) - 0.5) * 0.6;
    const int mode = trial % 4;  // on the outline with a window, one tap, and the two references
    a.reach_px = 6.5, a.fit_search_px = 1.5;
    a.search_px = mode == 1 ? 0.0 : 1.5;
    a.offset_px = mode == 2 ? -5.0 : mode == 3 ? 5.0 : 0.0;
    const int n = 1 + int(U(rng) * 70);  // tails of every length
    const size_t len = size_t(n);
    std::vector<float> qx(len), qy(len), nx(len), ny(len), h(len);
    for (int i = 0; i < n; ++i) {
      qx[size_t(i)] = float(U(rng) * 60), qy[size_t(i)] = float(U(rng) * 50);
      const double t = 6.3 * U(rng);
      nx[size_t(i)] = float(std::cos(t)), ny[size_t(i)] = float(std::sin(t));
      h[size_t(i)] = float(U(rng) < 0.3 ? 0.0 : 30 * U(rng));
    }
    std::vector<float> b1(len, -1), b2(len, -2);
    std::vector<std::uint8_t> v1(len, 7), v2(len, 9);
    EdgeTapsScalar(a, qx.data(), qy.data(), nx.data(), ny.data(), h.data(), n, b1.data(), v1.data());
    EdgeTapsAvx2(a, qx.data(), qy.data(), nx.data(), ny.data(), h.data(), n, b2.data(), v2.data());
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(v1[size_t(i)], v2[size_t(i)]) << "trial " << trial << " sample " << i;
      ASSERT_EQ(std::memcmp(&b1[size_t(i)], &b2[size_t(i)], sizeof(float)), 0)
          << "trial " << trial << " sample " << i << ": " << b1[size_t(i)] << " vs " << b2[size_t(i)];
      scored += v1[size_t(i)];
      windows += v1[size_t(i)] && a.search_px > 0;
    }
    total += n;
  }
  // the comparison covered scored samples with windows, and samples not scored
  EXPECT_GT(windows, 1000);
  EXPECT_GT(scored, total / 5);
  EXPECT_LT(scored, total);
}

TEST(EdgeKernels, ScalarFindsTheEdgeItSits) {
  // a vertical step edge at x = 50 (0 -> 100): a sample on it with its normal
  // across the edge scores half the step per px; one far from it scores 0
  cv::Mat1f img(100, 100, 0.f);
  img(cv::Rect(50, 0, 50, 100)) = 100.f;
  EdgeTapArgs a;
  a.image = img.ptr<float>(0);
  a.step = std::ptrdiff_t(img.step1());
  a.width = a.height = 100;
  const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::copy(I, I + 9, a.D);
  a.reach_px = 6.5, a.fit_search_px = 1.5, a.search_px = 1.5;
  const float qx[2] = {49.5f, 20.f}, qy[2] = {50.f, 50.f}, nx[2] = {1, 1}, ny[2] = {0, 0}, h[2] = {0, 0};
  float best[2];
  std::uint8_t valid[2];
  EdgeTapsScalar(a, qx, qy, nx, ny, h, 2, best, valid);
  EXPECT_EQ(valid[0], 1);
  EXPECT_EQ(valid[1], 1);
  EXPECT_NEAR(best[0], 50.f, 1e-3);
  EXPECT_EQ(best[1], 0.f);
  // too near the border for the reference window: not scored
  const float qb[1] = {3.f};
  EdgeTapsScalar(a, qb, qy, nx, ny, h, 1, best, valid);
  EXPECT_EQ(valid[0], 0);
}

TEST(ShiftKernels, Avx2EqualsScalarBitForBit) {
  if (!CpuHasAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(61206);
  std::uniform_real_distribution<float> U(0, 1);
  for (int trial = 0; trial < 60; ++trial) {
    const int n = 3 + trial * 2, B = 1 + trial % 61;  // odd and even lengths, every tail
    const int lda = B + trial % 3, ldb = n + trial % 5;  // row steps beyond the rows
    std::vector<float> a(size_t(n * lda)), bt(size_t(B * ldb));
    for (float& v : a) v = U(rng) < 0.6f ? 0.f : U(rng);  // sparse, like sqrt histograms
    for (float& v : bt) v = U(rng) < 0.6f ? 0.f : U(rng);
    std::vector<double> s1(size_t(n), -1), s2(size_t(n), -2);
    std::vector<float> row(s1.size());
    ShiftSumsScalar(a.data(), lda, bt.data(), ldb, n, B, s1.data(), row.data());
    ShiftSumsAvx2(a.data(), lda, bt.data(), ldb, n, B, s2.data(), row.data());
    ASSERT_EQ(std::memcmp(s1.data(), s2.data(), s1.size() * sizeof(double)), 0) << "n " << n << " B " << B;
    // and the sums are the shift correlations they stand for
    for (int k = 0; k < n; k += 7) {
      double want = 0;
      for (int j = 0; j < n; ++j)
        for (int b = 0; b < B; ++b)
          want += double(a[size_t(j * lda + b)]) * bt[size_t(b * ldb + (j + k) % n)];
      EXPECT_NEAR(s1[size_t(k)], want, 1e-4 * (1 + want)) << "n " << n << " k " << k;
    }
  }
}

}  // namespace
}  // namespace mvkp::internal
