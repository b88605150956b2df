#include "mvkp/aerial/cast_shadows.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/city/synth_city.h"
#include "mvkp/core/error.h"

namespace mvkp {
namespace {

// The true cast shadows of a generated scene: where its twin with the sun
// overhead is clearly brighter.
cv::Mat1b TrueShadows(const City& c, const City& overhead) {
  cv::Mat1b truth(c.photo.size(), uint8_t(0));
  for (int y = 0; y < c.photo.rows; ++y)
    for (int x = 0; x < c.photo.cols; ++x) {
      const cv::Vec3b p = c.photo.at<cv::Vec3b>(y, x), q = overhead.photo.at<cv::Vec3b>(y, x);
      truth(y, x) = (q[0] + q[1] + q[2] + 3) > 1.25f * (p[0] + p[1] + p[2] + 3) ? 255 : 0;
    }
  return truth;
}

double AngleGap(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 360.0);
  return std::min(d, 360.0 - d);
}

// At the true pose the sun is found (the shadows point away from it, about
// as long as the sun's elevation makes them), the relit pixels are mostly
// true shadow and the relit photo is closer to its twin without cast
// shadows there. Suburbs (lean, hills, hedges; coarse photos), dense towns
// and civic centres of seed 131, which the method was not tuned on (24 of
// its scenes at the true pose, GCC build: every sun within 8 deg, precision
// 0.73-0.97). At least 5 of these 6 suns must be right.
TEST(CastShadows, TheSunIsFittedAndTheShadowsRelitAtTheTruePose) {
  struct Case {
    const char* style;
    int scene;
  };
  int right_sun = 0;
  for (const Case k : {Case{"suburb", 2}, Case{"suburb", 6}, Case{"dense", 3}, Case{"dense", 5}, Case{"civic", 2},
                       Case{"civic", 6}}) {
    CityOptions o;
    o.style = k.style;
    const std::uint64_t seed = 131u * 1000003u + std::uint64_t(k.scene);
    const City c = MakeCity(o, seed);
    CityOptions up = o;
    up.sun_elevation_deg = 90, up.sun_azimuth_deg = 0;
    const City n = MakeCity(up, seed);
    const double res = c.options.res_m;
    CastShadowFit fit;
    const cv::Mat relit =
        RelightCastShadows(c.photo, 1.0, c.photo_to_depth, c.lean * (1.0 / res), SegmentDepth(c.depth), {}, &fit);
    const std::string what = std::string(k.style) + " " + std::to_string(k.scene);
    ASSERT_TRUE(fit.applied) << what << ": " << fit.reason;
    EXPECT_TRUE(fit.found);
    const bool sun_right = AngleGap(fit.azimuth_deg, c.sun_azimuth_deg + 180) <= 15.0;
    right_sun += sun_right;
    const double k_true = 1.0 / (std::tan(c.sun_elevation_deg * CV_PI / 180) * res);
    if (sun_right) {
      EXPECT_LT(std::abs(std::log(fit.length_px_per_m / k_true)), 0.8) << what << ": " << fit.length_px_per_m
                                                                        << " against " << k_true;
    }
    EXPECT_GE(fit.margin, 0.15) << what;
    for (int ch = 0; ch < 3; ++ch) EXPECT_LT(fit.log_step[ch], -0.1) << what;
    const cv::Mat1b truth = TrueShadows(c, n);
    cv::Mat diff;
    cv::absdiff(relit, c.photo, diff);
    cv::Mat1b changed;
    cv::cvtColor(diff, changed, cv::COLOR_BGR2GRAY);
    changed = changed > 8;
    const double hit = cv::countNonZero(changed & truth), relit_px = cv::countNonZero(changed);
    const double precision = hit / relit_px, recall = hit / cv::countNonZero(truth);
    std::printf("%s: sun %.0f (truth %.0f), k %.2f (truth %.2f), margin %.2f, relit %.1f %%, precision %.2f, recall "
                "%.2f\n",
                what.c_str(), fit.azimuth_deg, std::fmod(c.sun_azimuth_deg + 180, 360.0), fit.length_px_per_m, k_true,
                fit.margin, 100 * fit.fraction, precision, recall);
    EXPECT_GT(precision, 0.65) << what;
    // suburbs' hedges and trees cast shadows the depth's buildings do not
    if (sun_right) {
      EXPECT_GT(recall, std::string(k.style) == "suburb" ? 0.15 : 0.3) << what;
    }
    cv::Mat3f a, b, r;
    c.photo.convertTo(a, CV_32F), n.photo.convertTo(b, CV_32F), relit.convertTo(r, CV_32F);
    const cv::Scalar before = cv::mean(cv::abs(a - b), truth), after = cv::mean(cv::abs(r - b), truth);
    for (int ch = 0; ch < 3; ++ch) EXPECT_LT(after[ch], before[ch]) << what << " channel " << ch;
  }
  // GCC x86-64: 6 of 6. The scenes differ by compiler (clang: dense 3 got
  // a sun 43 deg off, its relit pixels still 88 % shadow).
  EXPECT_GE(right_sun, 5);
}

// A pose far from the truth, and a photo of other ground: no sun stands out,
// and the photo comes back unchanged.
TEST(CastShadows, NoSunAtAWrongPose) {
  CityOptions o;
  o.style = "suburb";
  const City c = MakeCity(o, 131u * 1000003u + 3u);
  const std::vector<BuildingRegion> regions = SegmentDepth(c.depth);
  const cv::Matx33d shift(1, 0, 90, 0, 1, -70, 0, 0, 1);
  const cv::Matx33d turn(0, -1, double(c.depth.cols), 1, 0, 0, 0, 0, 1);
  int refused = 0;
  for (const cv::Matx33d& wrong : {shift * c.photo_to_depth, turn * c.photo_to_depth}) {
    CastShadowFit fit;
    const cv::Mat out = RelightCastShadows(c.photo, 1.0, wrong, {}, regions, {}, &fit);
    if (!fit.applied) {
      EXPECT_EQ(out.data, c.photo.data);
      ++refused;
    }
    std::printf("wrong pose: %s (darkness %.3f, margin %.3f)\n", fit.applied ? "relit" : fit.reason.c_str(),
                fit.contrast, fit.margin);
  }
  EXPECT_EQ(refused, 2);
  CityOptions other = o;
  other.overlap = false;
  const City g = MakeCity(other, 131u * 1000003u + 4u);
  CastShadowFit fit;
  RelightCastShadows(g.photo, 1.0, g.photo_to_depth, {}, SegmentDepth(g.depth), {}, &fit);
  EXPECT_FALSE(fit.applied) << "other ground: darkness " << fit.contrast << ", margin " << fit.margin;
}

TEST(CastShadows, BadInput) {
  CastShadowOptions bad;
  bad.azimuths = 2;
  EXPECT_THROW(RelightCastShadows(cv::Mat3b(10, 10), 1.0, cv::Matx33d::eye(), {}, {}, bad), Error);
  CastShadowFit fit;
  const cv::Mat grey(20, 20, CV_8U, cv::Scalar(3));
  EXPECT_EQ(RelightCastShadows(grey, 1.0, cv::Matx33d::eye(), {}, {}, {}, &fit).data, grey.data);
  EXPECT_FALSE(fit.applied);
  const cv::Mat3b colour(20, 20, cv::Vec3b(1, 2, 3));
  EXPECT_EQ(RelightCastShadows(colour, 1.0, cv::Matx33d::eye(), {}, {}, {}, &fit).data, colour.data);
  EXPECT_FALSE(fit.applied);  // no building
}

}  // namespace
}  // namespace mvkp
