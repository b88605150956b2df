#include "mvkp/augment/augment.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/augment/internal/code_kernels.h"
#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {
namespace {

std::vector<int> Row(const cv::Mat& codes, int i) {
  std::vector<int> r(codes.cols);
  for (int j = 0; j < codes.cols; ++j)
    r[j] = codes.depth() == CV_8U ? codes.at<std::uint8_t>(i, j) : codes.at<std::uint16_t>(i, j);
  return r;
}

bool IsPermutation(std::vector<int> r) {
  std::sort(r.begin(), r.end());
  for (int j = 0; j < int(r.size()); ++j)
    if (r[j] != j + 1) return false;
  return true;
}

std::vector<cv::KeyPoint> Points(const std::vector<cv::Point2f>& p) {
  std::vector<cv::KeyPoint> k;
  for (const auto& q : p) k.emplace_back(q, 1.f);
  return k;
}

// Hand-worked example (k = 2, dim 4). Positions: P0 (0,0), P1 (1,0), P2 (0,2),
// P3 (5,5). Nearest: P0 -> P1, P2 | next P3; P1 -> P0, P2 | P3;
// P2 -> P0, P1 | P3; P3 -> P2, P1 | P0.
//   D0 = [0 0 4 0], D1 = [1 2 3 0], D2 = [3 0 1 0], D3 = [5 5 4 9]
//   R(P0) = [1 2 1 0] + [3 0 3 0] = [4 2 4 0]   tie dims 0, 2
//     + |D3 - D0| = [5 5 0 9] -> R' = [9 7 4 9]: dim 2 before dim 0
//     local  A = [4 2 3 1]
//     global mean = [2.25 1.75 3 2.25]: dim 0 before dim 2 -> A = [3 2 4 1]
//   R(P1) = [1 2 1 0] + [2 2 2 0] = [3 4 3 0]   tie dims 0, 2
//     + |D3 - D1| = [4 3 1 9] -> R'0 = 7, R'2 = 4: local A = [3 4 2 1]
//     global: dim 0 first -> A = [2 4 3 1]
//   R(P2) = [3 0 3 0] + [2 2 2 0] = [5 2 5 0]   tie dims 0, 2
//     + |D3 - D2| = [2 5 3 9] -> 7 vs 8: dim 0 first, A = [3 2 4 1] (both modes)
//   R(P3) = [4 3 1 9] + [2 5 3 9] = [6 8 4 18]   no tie: A = [2 3 1 4]
struct Hand {
  std::vector<cv::KeyPoint> kps = Points({{0, 0}, {1, 0}, {0, 2}, {5, 5}});
  cv::Mat desc = (cv::Mat_<float>(4, 4) << 0, 0, 4, 0, 1, 2, 3, 0, 3, 0, 1, 0, 5, 5, 4, 9);
};

TEST(Augment, HandWorkedLocal) {
  Hand h;
  AugmentOptions o;
  o.k = 2;
  const cv::Mat a = Augment(h.kps, h.desc, o);
  ASSERT_EQ(a.type(), CV_8UC1);
  ASSERT_EQ(a.rows, 4);
  EXPECT_EQ(Row(a, 0), (std::vector<int>{4, 2, 3, 1}));
  EXPECT_EQ(Row(a, 1), (std::vector<int>{3, 4, 2, 1}));
  EXPECT_EQ(Row(a, 2), (std::vector<int>{3, 2, 4, 1}));
  EXPECT_EQ(Row(a, 3), (std::vector<int>{2, 3, 1, 4}));
  // Bytes give the same codes.
  cv::Mat d8;
  h.desc.convertTo(d8, CV_8U);
  EXPECT_EQ(cv::norm(Augment(h.kps, d8, o), a, cv::NORM_INF), 0);
}

TEST(Augment, HandWorkedGlobal) {
  Hand h;
  AugmentOptions o;
  o.k = 2;
  o.ties = TieMode::kGlobal;
  const cv::Mat a = Augment(h.kps, h.desc, o);
  EXPECT_EQ(Row(a, 0), (std::vector<int>{3, 2, 4, 1}));
  EXPECT_EQ(Row(a, 1), (std::vector<int>{2, 4, 3, 1}));
  EXPECT_EQ(Row(a, 2), (std::vector<int>{3, 2, 4, 1}));
  EXPECT_EQ(Row(a, 3), (std::vector<int>{2, 3, 1, 4}));
}

TEST(Augment, TieThatNeverBreaksFallsBackToIndex) {
  Hand h;
  AugmentOptions o;
  o.k = 2;
  o.max_tie_iterations = 0;  // no extra neighbours: ties go by index
  const cv::Mat a = Augment(h.kps, h.desc, o);
  EXPECT_EQ(Row(a, 0), (std::vector<int>{3, 2, 4, 1}));
  EXPECT_EQ(Row(a, 1), (std::vector<int>{2, 4, 3, 1}));
  // k = 3 uses every other keypoint; no extra one is left to break ties.
  // R(P0) = [1 2 1 0] + [3 0 3 0] + [5 5 0 9] = [9 7 4 9]: dims 0 and 3 tie.
  o.k = 3;
  o.max_tie_iterations = 5;
  EXPECT_EQ(Row(Augment(h.kps, h.desc, o), 0), (std::vector<int>{3, 2, 1, 4}));
  // A single keypoint: all R are 0, ordered by tie breaking alone.
  EXPECT_EQ(Row(Augment({h.kps[0]}, h.desc.row(0), o), 0), (std::vector<int>{1, 2, 3, 4}));
  o.ties = TieMode::kGlobal;  // mean = D0 = [0 0 4 0]
  EXPECT_EQ(Row(Augment({h.kps[0]}, h.desc.row(0), o), 0), (std::vector<int>{1, 2, 4, 3}));
}

// Brute-force reference of the definition (O(N^2) neighbours, O(dim^2) ranks).
cv::Mat ReferenceAugment(const std::vector<cv::KeyPoint>& kps, const cv::Mat& desc, const AugmentOptions& o) {
  const int n = int(kps.size()), dim = desc.cols;
  cv::Mat codes(n, dim, CV_8U);
  std::vector<double> mean(dim, 0);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < dim; ++j) mean[j] += desc.at<float>(i, j);
  for (int i = 0; i < n; ++i) {
    std::vector<std::pair<double, int>> all;
    for (int m = 0; m < n; ++m) {
      if (m == i) continue;
      const double dx = double(kps[m].pt.x) - kps[i].pt.x, dy = double(kps[m].pt.y) - kps[i].pt.y;
      all.push_back({dx * dx + dy * dy, m});
    }
    std::sort(all.begin(), all.end());
    const int k = std::min<int>(o.k, int(all.size()));
    std::vector<int> members;
    for (int t = 0; t < k; ++t) members.push_back(all[t].second);
    std::sort(members.begin(), members.end());
    // seq[j] = (R, R after 1 extra, ...) for local; (R, mean) for global.
    std::vector<std::vector<double>> seq(dim);
    for (int j = 0; j < dim; ++j) {
      float r = 0;
      for (int m : members) r += std::fabs(desc.at<float>(m, j) - desc.at<float>(i, j));
      seq[j].push_back(r);
      if (o.ties == TieMode::kLocal) {
        for (int t = k; t < std::min<int>(k + o.max_tie_iterations, int(all.size())); ++t) {
          r += std::fabs(desc.at<float>(all[t].second, j) - desc.at<float>(i, j));
          seq[j].push_back(r);
        }
      } else {
        seq[j].push_back(mean[j]);
      }
    }
    for (int j = 0; j < dim; ++j) {
      int rank = 1;
      for (int m = 0; m < dim; ++m)
        if (seq[m] < seq[j] || (seq[m] == seq[j] && m < j)) ++rank;
      codes.at<std::uint8_t>(i, j) = std::uint8_t(rank);
    }
  }
  return codes;
}

TEST(Augment, MatchesBruteForceReference) {
  std::mt19937 rng(7);
  for (TieMode mode : {TieMode::kLocal, TieMode::kGlobal}) {
    for (int trial = 0; trial < 6; ++trial) {
      const int n = 1 + trial * 37, dim = 3 + trial * 5;
      std::vector<cv::Point2f> p;
      std::uniform_int_distribution<int> coord(0, trial % 2 ? 15 : 400);  // small range: duplicate points
      for (int i = 0; i < n; ++i) p.emplace_back(float(coord(rng)), float(coord(rng) / (trial == 3 ? 50 : 1)));
      cv::Mat desc(n, dim, CV_32F);
      std::uniform_int_distribution<int> val(0, trial % 3 == 0 ? 2 : 255);  // few values: many ties
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < dim; ++j) desc.at<float>(i, j) = float(val(rng));
      AugmentOptions o;
      o.k = 1 + trial;
      o.ties = mode;
      o.max_tie_iterations = trial;
      const cv::Mat got = Augment(Points(p), desc, o), want = ReferenceAugment(Points(p), desc, o);
      EXPECT_EQ(cv::norm(got, want, cv::NORM_INF), 0) << "trial " << trial << " mode " << int(mode);
    }
  }
}

TEST(Augment, CodesArePermutations) {
  std::mt19937 rng(3);
  for (int dim : {1, 20, 128, 300}) {
    const int n = 200;
    std::vector<cv::Point2f> p;
    std::uniform_real_distribution<float> u(0, 500);
    for (int i = 0; i < n; ++i) p.emplace_back(u(rng), u(rng));
    cv::Mat desc(n, dim, CV_32F);
    cv::randu(desc, 0, 4);
    for (TieMode mode : {TieMode::kLocal, TieMode::kGlobal}) {
      AugmentOptions o;
      o.ties = mode;
      const cv::Mat a = Augment(Points(p), desc, o);
      EXPECT_EQ(a.type(), dim <= 255 ? CV_8UC1 : CV_16UC1);
      ASSERT_EQ(a.rows, n);
      ASSERT_EQ(a.cols, dim);
      for (int i = 0; i < n; ++i) ASSERT_TRUE(IsPermutation(Row(a, i))) << dim << " row " << i;
    }
  }
}

TEST(Augment, InvariantToSimilarityOfPositionsAndDescriptorScale) {
  std::mt19937 rng(11);
  const int n = 300, dim = 32;
  std::uniform_real_distribution<double> u(0, 600);
  std::vector<cv::Point2f> p;
  for (int i = 0; i < n; ++i) p.emplace_back(float(u(rng)), float(u(rng)));
  cv::Mat desc(n, dim, CV_32F);
  std::uniform_int_distribution<int> val(0, 20);  // integer values: ties to break
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < dim; ++j) desc.at<float>(i, j) = float(val(rng));
  for (TieMode mode : {TieMode::kLocal, TieMode::kGlobal}) {
    AugmentOptions o;
    o.ties = mode;
    const cv::Mat base = Augment(Points(p), desc, o);
    const double a = 37 * CV_PI / 180, s = 1.7;
    std::vector<cv::Point2f> q;
    for (const auto& pt : p)
      q.emplace_back(float(s * (std::cos(a) * pt.x - std::sin(a) * pt.y) + 100),
                     float(s * (std::sin(a) * pt.x + std::cos(a) * pt.y) - 50));
    EXPECT_EQ(cv::norm(Augment(Points(q), desc, o), base, cv::NORM_INF), 0) << int(mode);
    for (double c : {3.0, 0.5}) {
      cv::Mat scaled = desc * c;
      EXPECT_EQ(cv::norm(Augment(Points(p), scaled, o), base, cv::NORM_INF), 0) << c;
    }
  }
}

TEST(Augment, MetricsOnKnownCodes) {
  const std::vector<std::uint8_t> id = {1, 2, 3, 4, 5, 6}, rev = {6, 5, 4, 3, 2, 1}, swp = {2, 1, 3, 4, 5, 6};
  const int d = 6;
  using M = AugmentMetric;
  EXPECT_DOUBLE_EQ(Similarity(id.data(), id.data(), d, M::kSpearman), 1.0);
  EXPECT_DOUBLE_EQ(Similarity(id.data(), rev.data(), d, M::kSpearman), 0.0);
  EXPECT_DOUBLE_EQ(Similarity(id.data(), swp.data(), d, M::kSpearman), 1.0 - 3.0 * 2 / (6 * 35));
  EXPECT_DOUBLE_EQ(Dissimilarity(id.data(), swp.data(), d, M::kSpearman), std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(Dissimilarity(id.data(), rev.data(), d, M::kSpearman), std::sqrt(70.0));
  EXPECT_DOUBLE_EQ(Similarity(id.data(), id.data(), d, M::kKendall), 1.0);
  EXPECT_DOUBLE_EQ(Similarity(id.data(), rev.data(), d, M::kKendall), -1.0);
  EXPECT_DOUBLE_EQ(Similarity(id.data(), swp.data(), d, M::kKendall), 1.0 - 2.0 / 15);  // 1 discordant of 15
  EXPECT_DOUBLE_EQ(Dissimilarity(id.data(), swp.data(), d, M::kKendall), 1.0 / 15);
  EXPECT_DOUBLE_EQ(Dissimilarity(id.data(), rev.data(), d, M::kKendall), 1.0);
  EXPECT_DOUBLE_EQ(Dissimilarity(id.data(), swp.data(), d, M::kCount), 2.0);
  EXPECT_DOUBLE_EQ(Dissimilarity(id.data(), rev.data(), d, M::kCount), 6.0);
  EXPECT_DOUBLE_EQ(Similarity(id.data(), swp.data(), d, M::kCount), 4.0 / 6);
  EXPECT_DOUBLE_EQ(Similarity(id.data(), id.data(), d, M::kCount), 1.0);
  // cv::Mat rows and 16-bit codes agree with the byte form.
  const cv::Mat a(1, d, CV_8U, const_cast<std::uint8_t*>(id.data()));
  const cv::Mat b(1, d, CV_8U, const_cast<std::uint8_t*>(swp.data()));
  cv::Mat a16, b16;
  a.convertTo(a16, CV_16U);
  b.convertTo(b16, CV_16U);
  for (M m : {M::kSpearman, M::kKendall, M::kCount}) {
    EXPECT_DOUBLE_EQ(Similarity(a, b, m), Similarity(id.data(), swp.data(), d, m));
    EXPECT_DOUBLE_EQ(Similarity(a16, b16, m), Similarity(id.data(), swp.data(), d, m));
    EXPECT_DOUBLE_EQ(Dissimilarity(a16, b16, m), Dissimilarity(id.data(), swp.data(), d, m));
  }
  EXPECT_THROW(Similarity(a, b16, M::kSpearman), Error);
}

cv::Mat RandomCodes(int n, int dim, std::mt19937& rng, bool repeats = false) {
  cv::Mat c(n, dim, CV_8U);
  std::vector<int> perm(dim);
  for (int i = 0; i < n; ++i) {
    std::iota(perm.begin(), perm.end(), 1);
    std::shuffle(perm.begin(), perm.end(), rng);
    if (repeats && dim > 1) perm[0] = perm[1];
    for (int j = 0; j < dim; ++j) c.at<std::uint8_t>(i, j) = std::uint8_t(perm[j]);
  }
  return c;
}

TEST(Augment, KnnMatchCodesEqualsBruteForce) {
  std::mt19937 rng(5);
  for (int dim : {1, 2, 7, 16, 33, 128}) {
    for (bool repeats : {false, true}) {
      const cv::Mat c1 = RandomCodes(40, dim, rng, repeats), c2 = RandomCodes(57, dim, rng);
      cv::Mat c2dup;
      cv::vconcat(c2, c2.rowRange(0, 5), c2dup);  // exact duplicates: ties go to the smaller index
      for (AugmentMetric m : {AugmentMetric::kSpearman, AugmentMetric::kKendall, AugmentMetric::kCount}) {
        const auto got = KnnMatchCodes(c1, c2dup, m);
        ASSERT_EQ(int(got.size()), c1.rows);
        for (int i = 0; i < c1.rows; ++i) {
          std::vector<std::pair<double, int>> all;
          for (int r = 0; r < c2dup.rows; ++r) all.push_back({Dissimilarity(c1.row(i), c2dup.row(r), m), r});
          std::sort(all.begin(), all.end());
          EXPECT_EQ(got[i].best, all[0].second) << dim << " " << int(m);
          EXPECT_EQ(got[i].second, all[1].second) << dim << " " << int(m);
          EXPECT_NEAR(got[i].d1, all[0].first, 1e-12);
          EXPECT_NEAR(got[i].d2, all[1].first, 1e-12);
        }
      }
    }
  }
  // One candidate: no second; none: no best.
  const cv::Mat c = RandomCodes(3, 8, rng);
  const auto one = KnnMatchCodes(c, c.row(1), AugmentMetric::kSpearman);
  EXPECT_EQ(one[0].best, 0);
  EXPECT_EQ(one[0].second, -1);
  EXPECT_TRUE(std::isinf(one[0].d2));
  EXPECT_EQ(MatchCodes(c, c.row(1), AugmentMetric::kSpearman, 0.8).size(), 3u);
  const auto none = KnnMatchCodes(c, cv::Mat(), AugmentMetric::kSpearman);
  EXPECT_EQ(none[0].best, -1);
  EXPECT_TRUE(MatchCodes(c, cv::Mat(), AugmentMetric::kSpearman, 0.8).empty());
  EXPECT_TRUE(KnnMatchCodes(cv::Mat(), c, AugmentMetric::kSpearman).empty());
}

TEST(Augment, SimdKernelsEqualScalar) {
  if (!augment_internal::CpuHasAvx2()) GTEST_SKIP() << "no AVX2";
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int dim = 1; dim <= 255; dim += (dim < 40 ? 1 : 23)) {
    for (int n : {1, 2, 5}) {
      std::vector<std::uint8_t> q(dim), rows(std::size_t(n) * dim);
      for (auto& v : q) v = std::uint8_t(byte(rng));
      for (auto& v : rows) v = std::uint8_t(byte(rng));
      std::vector<std::int32_t> a(n), b(n);
      augment_internal::SumSqDiffRowsScalar(q.data(), rows.data(), n, dim, a.data());
      augment_internal::SumSqDiffRowsAvx2(q.data(), rows.data(), n, dim, b.data());
      EXPECT_EQ(a, b) << dim;
      for (std::size_t t = 0; t < rows.size(); t += 3) rows[t] = q[t % dim];  // some equal positions
      augment_internal::CountDiffRowsScalar(q.data(), rows.data(), n, dim, a.data());
      augment_internal::CountDiffRowsAvx2(q.data(), rows.data(), n, dim, b.data());
      EXPECT_EQ(a, b) << dim;
    }
  }
  std::vector<std::uint64_t> q(9), rows(27);
  for (auto& v : q) v = (std::uint64_t(rng()) << 32) | rng();
  for (auto& v : rows) v = (std::uint64_t(rng()) << 32) | rng();
  std::vector<std::int32_t> a(3), b(3);
  augment_internal::XorPopcountRowsScalar(q.data(), rows.data(), 3, 9, a.data());
  augment_internal::XorPopcountRowsAvx2(q.data(), rows.data(), 3, 9, b.data());
  EXPECT_EQ(a, b);
}

TEST(Augment, BadInput) {
  Hand h;
  EXPECT_THROW(Augment(h.kps, h.desc.rowRange(0, 3)), Error);  // count mismatch
  try {
    cv::Mat d64;
    h.desc.convertTo(d64, CV_64F);
    Augment(h.kps, d64);
    FAIL() << "CV_64F accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("mismatched descriptor type"), std::string::npos) << e.what();
  }
  cv::Mat two_channels(4, 2, CV_32FC2, cv::Scalar(0, 0));
  EXPECT_THROW(Augment(h.kps, two_channels), Error);
  AugmentOptions o;
  o.k = 0;
  EXPECT_THROW(Augment(h.kps, h.desc, o), Error);
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.max_tie_iterations = -1;
  EXPECT_THROW(o.Check(), Error);
  EXPECT_TRUE(Augment({}, cv::Mat()).empty());
  EXPECT_THROW(Augment({}, h.desc), Error);
  auto bad = h.kps;
  bad[2].pt.x = std::nanf("");
  EXPECT_THROW(Augment(bad, h.desc), Error);
  // Code sets that do not fit together; bad ratios.
  const cv::Mat c = Augment(h.kps, h.desc);
  cv::Mat c16;
  c.convertTo(c16, CV_16U);
  EXPECT_THROW(KnnMatchCodes(c, c16, AugmentMetric::kSpearman), Error);
  EXPECT_THROW(KnnMatchCodes(c, c.colRange(0, 3), AugmentMetric::kSpearman), Error);
  EXPECT_THROW(KnnMatchCodes(h.desc, h.desc, AugmentMetric::kSpearman), Error);
  EXPECT_THROW(MatchCodes(c, c, AugmentMetric::kSpearman, 0), Error);
  EXPECT_THROW(MatchCodes(c, c, AugmentMetric::kSpearman, 1.5), Error);
}

// ---- real images

cv::Mat LoadSample(const std::string& name) {
  const cv::Mat m = cv::imread(std::string(MVKP_SOURCE_DIR) + "/samples/" + name, cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(m.empty()) << name;
  return m;
}

// Rotates by deg and scales by s about the image centre (same canvas size).
cv::Mat Warp(const cv::Mat& img, double deg, double s, cv::Mat& out) {
  const cv::Mat A = cv::getRotationMatrix2D(cv::Point2f(img.cols / 2.f, img.rows / 2.f), deg, s);
  cv::warpAffine(img, out, A, img.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return A;
}

cv::Point2f Apply(const cv::Mat& A, cv::Point2f p) {
  return {float(A.at<double>(0, 0) * p.x + A.at<double>(0, 1) * p.y + A.at<double>(0, 2)),
          float(A.at<double>(1, 0) * p.x + A.at<double>(1, 1) * p.y + A.at<double>(1, 2))};
}

TEST(Augment, AugmentedSiftMatchesRotatedScaledCopy) {
  const cv::Mat big = LoadSample("starry_night.jpg");  // 400 x 319
  ASSERT_FALSE(big.empty());
  cv::Mat warped;
  const cv::Mat A = Warp(big, 20, 0.8, warped);
  auto sift = cv::SIFT::create();
  std::vector<cv::KeyPoint> k1, k2;
  cv::Mat d1, d2;
  sift->detectAndCompute(big, cv::noArray(), k1, d1);
  sift->detectAndCompute(warped, cv::noArray(), k2, d2);
  ASSERT_GT(k1.size(), 200u);
  auto correct = [&](const std::vector<cv::DMatch>& m) {
    int ok = 0;
    for (const auto& x : m) ok += cv::norm(Apply(A, k1[x.queryIdx].pt) - k2[x.trainIdx].pt) < 3.0;
    return ok;
  };
  for (TieMode mode : {TieMode::kLocal, TieMode::kGlobal}) {
    AugmentOptions o;
    o.ties = mode;
    const cv::Mat c1 = Augment(k1, d1, o), c2 = Augment(k2, d2, o);
    for (AugmentMetric metric : {AugmentMetric::kSpearman, AugmentMetric::kKendall, AugmentMetric::kCount}) {
      const auto m = MatchCodes(c1, c2, metric, 0.8);
      const int ok = correct(m);
      std::printf("augmented SIFT %s %s, ratio 0.8: %zu matches, %d correct (%.2f); keypoints %zu / %zu\n",
                  mode == TieMode::kLocal ? "(L)" : "(G)",
                  metric == AugmentMetric::kSpearman  ? "spearman"
                  : metric == AugmentMetric::kKendall ? "kendall"
                                                      : "count",
                  m.size(), ok, m.empty() ? 0.0 : double(ok) / m.size(), k1.size(), k2.size());
      if (metric == AugmentMetric::kSpearman) {
        EXPECT_GE(ok, 50);
        EXPECT_GE(ok, 0.6 * double(m.size()));
      }
    }
  }
  // The base descriptors, for comparison (printed only).
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(cv::NORM_L2).knnMatch(d1, d2, knn, 2);
  std::vector<cv::DMatch> base;
  for (const auto& v : knn)
    if (v.size() == 2 && v[0].distance < 0.8f * v[1].distance) base.push_back(v[0]);
  std::printf("plain SIFT, ratio 0.8: %zu matches, %d correct\n", base.size(), correct(base));
}

// Timings, printed, not asserted: Augment against SIFT extraction on an
// 800-px image, one thread.
TEST(AugmentTiming, SiftImage800px) {
  cv::setNumThreads(1);
  cv::Mat img = LoadSample("starry_night.jpg"), big, warped;
  ASSERT_FALSE(img.empty());
  cv::resize(img, big, cv::Size(800, int(std::lround(800.0 * img.rows / img.cols))), 0, 0, cv::INTER_CUBIC);
  Warp(big, 20, 0.8, warped);
  auto sift = cv::SIFT::create();
  std::vector<cv::KeyPoint> k1, k2;
  cv::Mat d1, d2;
  double sift_ms = 1e30;
  for (int rep = 0; rep < 3; ++rep) {
    Timer t;
    sift->detectAndCompute(big, cv::noArray(), k1, d1);
    sift_ms = std::min(sift_ms, t.ElapsedMs());
  }
  sift->detectAndCompute(warped, cv::noArray(), k2, d2);
  for (TieMode mode : {TieMode::kLocal, TieMode::kGlobal}) {
    AugmentOptions o;
    o.ties = mode;
    cv::Mat c1;
    double aug_ms = 1e30;
    for (int rep = 0; rep < 5; ++rep) {
      Timer t;
      c1 = Augment(k1, d1, o);
      aug_ms = std::min(aug_ms, t.ElapsedMs());
    }
    std::printf("%dx%d, %zu SIFT keypoints: SIFT detectAndCompute %.1f ms, Augment %s %.2f ms (%.2f %%)\n", big.cols,
                big.rows, k1.size(), sift_ms, mode == TieMode::kLocal ? "(L)" : "(G)", aug_ms,
                100 * aug_ms / sift_ms);
  }
  {
    // A more typical keypoint count.
    std::vector<cv::KeyPoint> k3;
    cv::Mat d3;
    auto sift3 = cv::SIFT::create(3000);
    Timer t;
    sift3->detectAndCompute(big, cv::noArray(), k3, d3);
    const double s3 = t.ElapsedMs();
    double a3 = 1e30;
    for (int rep = 0; rep < 5; ++rep) {
      t.Restart();
      Augment(k3, d3);
      a3 = std::min(a3, t.ElapsedMs());
    }
    std::printf("SIFT(nfeatures 3000), %zu keypoints: detectAndCompute %.1f ms, Augment (L) %.2f ms (%.2f %%)\n",
                k3.size(), s3, a3, 100 * a3 / s3);
  }
  const cv::Mat c1 = Augment(k1, d1), c2 = Augment(k2, d2);
  for (AugmentMetric m : {AugmentMetric::kSpearman, AugmentMetric::kKendall, AugmentMetric::kCount}) {
    // Kendall is ~12x slower: timed on the first 1000 query rows only.
    const cv::Mat q = m == AugmentMetric::kKendall ? c1.rowRange(0, std::min(1000, c1.rows)) : c1;
    Timer t;
    const auto two = KnnMatchCodes(q, c2, m);
    const double ms = t.ElapsedMs();
    std::printf("KnnMatchCodes %s %d x %d x %d: %.1f ms (%.1f ns per pair)\n",
                m == AugmentMetric::kSpearman ? "spearman" : m == AugmentMetric::kKendall ? "kendall" : "count",
                q.rows, c2.rows, c1.cols, ms, 1e6 * ms / (double(q.rows) * c2.rows));
  }
  // Spearman on the scalar reference kernel, for the SIMD gain.
  {
    const std::size_t n2 = std::size_t(c2.rows);
    std::vector<std::int32_t> d(n2);
    Timer t;
    std::int64_t sink = 0;
    for (int i = 0; i < c1.rows; ++i) {
      augment_internal::SumSqDiffRowsScalar(c1.ptr<std::uint8_t>(i), c2.ptr<std::uint8_t>(), n2, c1.cols,
                                            d.data());
      sink += d[i % n2];
    }
    std::printf("Spearman scalar reference kernel alone: %.1f ms (%lld)\n", t.ElapsedMs(), (long long)(sink % 7));
  }
  // BFMatcher on the float SIFT descriptors, for scale.
  {
    std::vector<std::vector<cv::DMatch>> knn;
    Timer t;
    cv::BFMatcher(cv::NORM_L2).knnMatch(d1, d2, knn, 2);
    std::printf("cv::BFMatcher L2 knn 2 on SIFT floats: %.1f ms\n", t.ElapsedMs());
  }
}

}  // namespace
}  // namespace mvkp
