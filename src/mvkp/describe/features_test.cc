#include "mvkp/describe/features.h"
#include "mvkp/describe/internal/orient_kernels.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace mvkp {
namespace {

cv::Mat Texture(int w, int h, std::uint64_t seed) {
  cv::Mat small(h / 8, w / 8, CV_8UC1), img;
  cv::RNG(seed).fill(small, cv::RNG::UNIFORM, 0, 255);
  cv::resize(small, img, cv::Size(w, h), 0, 0, cv::INTER_CUBIC);
  return img;
}

TEST(Describer, UnrotatedSamplingEqualsExactPatchProjection) {
  const cv::Mat img = Texture(128, 128, 5);
  DescriberOptions o;
  o.orient = false;
  Describer d(o);
  wht::Projector proj({32, 20, true});
  for (int px : {40, 64, 81}) {
    std::vector<Keypoint> kps{{float(px), float(px - 3), 1.f, 0.f}};
    std::vector<float> desc(20);
    d.Compute(img, kps, desc.data());
    // The exact patch: pixels px-16 .. px+15.
    cv::Mat patch = img(cv::Rect(px - 16, px - 3 - 16, 32, 32)).clone();
    std::vector<std::int32_t> c(20);
    proj.Project(patch.ptr<std::uint8_t>(), 32, c.data());
    // Normalisation: block means' standard deviation times grid side.
    cv::Mat means;
    cv::resize(patch, means, cv::Size(8, 8), 0, 0, cv::INTER_AREA);
    cv::Mat mf;
    patch.convertTo(mf, CV_32F);
    cv::Mat bm(8, 8, CV_64F);
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) bm.at<double>(y, x) = cv::mean(mf(cv::Rect(x * 4, y * 4, 4, 4)))[0];
    cv::Scalar mu, sd;
    cv::meanStdDev(bm, mu, sd);
    for (int i = 0; i < 20; ++i) EXPECT_NEAR(desc[i], c[i] / 16.0 / (sd[0] * 8), 1e-3) << i;
  }
}

TEST(Describer, OrientedDescriptorsAreRotationInvariant) {
  const cv::Mat img = Texture(200, 200, 9);
  cv::Mat rot;
  const cv::Point2f c(99.5f, 99.5f);
  const cv::Mat R = cv::getRotationMatrix2D(c, 57.0, 1.0);
  cv::warpAffine(img, rot, R, img.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  Describer d{DescriberOptions{}};
  std::vector<Keypoint> a{{100.f, 100.f, 1.f, 0.f}, {80.f, 110.f, 1.f, 0.f}};
  std::vector<Keypoint> b;
  for (const auto& k : a) {
    const double x = R.at<double>(0, 0) * k.x + R.at<double>(0, 1) * k.y + R.at<double>(0, 2);
    const double y = R.at<double>(1, 0) * k.x + R.at<double>(1, 1) * k.y + R.at<double>(1, 2);
    b.push_back({float(x), float(y), 1.f, 0.f});
  }
  std::vector<float> da(40), db(40);
  d.Compute(img, a, da.data());
  d.Compute(rot, b, db.data());
  for (int i = 0; i < 2; ++i) {
    double dist = 0, norm = 0;
    for (int q = 0; q < 20; ++q) {
      dist += (da[i * 20 + q] - db[i * 20 + q]) * (da[i * 20 + q] - db[i * 20 + q]);
      norm += da[i * 20 + q] * da[i * 20 + q];
    }
    EXPECT_LT(std::sqrt(dist / norm), 0.25) << "keypoint " << i;
    const double dang = std::remainder(b[i].angle - a[i].angle + 57.0 * CV_PI / 180.0, 2 * CV_PI);
    EXPECT_LT(std::abs(dang), 0.15);  // the frame rotates with the image (y down: -57 deg)
  }
}

TEST(Describer, InvariantToAffineLighting) {
  const cv::Mat img = Texture(128, 128, 11);
  cv::Mat lit;
  img.convertTo(lit, CV_8U, 0.6, 40);
  Describer d{DescriberOptions{}};
  std::vector<Keypoint> a{{64.f, 64.f, 1.f, 0.f}}, b = a;
  std::vector<float> da(20), db(20);
  d.Compute(img, a, da.data());
  d.Compute(lit, b, db.data());
  for (int q = 0; q < 20; ++q) EXPECT_NEAR(da[q], db[q], 0.05 + 0.05 * std::abs(da[q]));
}

TEST(ExtractFeatures, ReturnsOneDescriptorPerKeypoint) {
  const cv::Mat img = Texture(320, 240, 2);
  FeatureOptions o;
  const Features f = ExtractFeatures(img, o);
  EXPECT_GT(f.keypoints.size(), 50u);
  EXPECT_LE(f.keypoints.size(), 500u);
  EXPECT_EQ(f.descriptors.rows, int(f.keypoints.size()));
  EXPECT_EQ(f.descriptors.cols, 20);
}

// The AVX2 disc moments equal the scalar reference (and a direct sum over the
// disc) for every radius the fast path takes, at random points of a random image.
TEST(DiscMoments, SimdEqualsScalarReference) {
  const internal::DiscMomentsFn simd = internal::DiscMomentsSimd();
  if (!simd) GTEST_SKIP() << "no AVX2 on this CPU";
  cv::Mat img(80, 96, CV_8UC1);
  cv::RNG rng(11);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  img.at<std::uint8_t>(40, 48) = 255;
  for (int r = 2; r <= internal::kMaxSimdRadius; ++r) {
    const internal::DiscTable t(r);
    for (int k = 0; k < 40; ++k) {
      const int px = rng.uniform(16, img.cols - 17), py = rng.uniform(r, img.rows - r);
      const std::uint8_t* c = img.ptr<std::uint8_t>(py) + px;
      std::int64_t a10 = -1, a01 = -1, b10 = -2, b01 = -2, d10 = 0, d01 = 0;
      internal::DiscMomentsScalar(c, std::ptrdiff_t(img.step[0]), t, a10, a01);
      simd(c, std::ptrdiff_t(img.step[0]), t, b10, b01);
      for (int v = -r; v <= r; ++v)
        for (int u = -r; u <= r; ++u)
          if (std::abs(u) <= t.umax[std::abs(v)]) {
            d10 += u * int(img.at<std::uint8_t>(py + v, px + u));
            d01 += v * int(img.at<std::uint8_t>(py + v, px + u));
          }
      ASSERT_EQ(a10, d10) << "r " << r;
      ASSERT_EQ(a01, d01) << "r " << r;
      ASSERT_EQ(b10, a10) << "r " << r << " at " << px << "," << py;
      ASSERT_EQ(b01, a01) << "r " << r << " at " << px << "," << py;
    }
  }
}

// The AVX2 row of rotated bilinear samples equals the scalar reference bit
// for bit (the describer's values must not depend on the CPU).
TEST(BilinearRow8, SimdEqualsScalarReferenceBitForBit) {
  if (internal::BestBilinearRow8() == &internal::BilinearRow8Scalar) GTEST_SKIP() << "no AVX2 on this CPU";
  cv::Mat img(90, 110, CV_32F);
  cv::RNG rng(12);
  rng.fill(img, cv::RNG::UNIFORM, 0.0, 255.0);
  const float offs[8] = {-14, -10, -6, -2, 2, 6, 10, 14};
  for (int k = 0; k < 2000; ++k) {
    const float a = float(rng.uniform(-CV_PI, CV_PI)), c = std::cos(a), s = std::sin(a);
    const float cx = float(rng.uniform(25.0, 84.0)), cy = float(rng.uniform(25.0, 64.0));
    const float oy = offs[k % 8];
    float x[8], y[8];
    internal::BilinearRow8Scalar(img.ptr<float>(), std::ptrdiff_t(img.step1()), cx, cy, c, s, offs, oy, x);
    internal::BilinearRow8Avx2(img.ptr<float>(), std::ptrdiff_t(img.step1()), cx, cy, c, s, offs, oy, y);
    for (int j = 0; j < 8; ++j) {
      std::uint32_t bx, by;
      std::memcpy(&bx, &x[j], 4);
      std::memcpy(&by, &y[j], 4);
      ASSERT_EQ(bx, by) << k << " lane " << j << ": " << x[j] << " vs " << y[j];
    }
  }
}

}  // namespace
}  // namespace mvkp
