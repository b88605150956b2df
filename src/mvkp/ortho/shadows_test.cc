#include "mvkp/ortho/shadows.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

// A nadir scene of its own (not synth-city's renderer): grass and paving in
// smooth blobs, textured; flat roofs of four colours; each building's cast
// shadow is its footprint swept along the shadow vector, on the ground only,
// with a soft edge. The shadow multiplies B, G, R by `ratio`.
struct ShadowScene {
  cv::Mat3b lit, shadowed;   // the same scene without and with cast shadows
  cv::Mat1b shadow_core;     // pixels fully in shadow, 2 px away from its edge
  cv::Mat1b shadow_any;      // pixels touched by the shadow at all
};

ShadowScene MakeScene(cv::Vec3f ratio, unsigned seed, cv::Point2f sun_vec = {26, 17}) {
  const int S = 800;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(0, 1);
  // ground: smooth noise -> two materials, plus fine texture
  cv::Mat1f blob(S / 16, S / 16), fine(S, S);
  cv::randu(blob, 0, 1);
  cv::resize(blob, blob, cv::Size(S, S), 0, 0, cv::INTER_CUBIC);
  cv::GaussianBlur(blob, blob, cv::Size(), 12);
  cv::theRNG().state = seed;
  cv::randn(fine, 0, 1);
  cv::GaussianBlur(fine, fine, cv::Size(), 1.5);
  cv::Mat3f img(S, S);
  const cv::Vec3f grass(62, 128, 84), paving(168, 172, 178);
  for (int y = 0; y < S; ++y)
    for (int x = 0; x < S; ++x) {
      const cv::Vec3f base = blob(y, x) > 0.5f ? paving : grass;
      img(y, x) = base * (1 + 0.06f * fine(y, x));
    }
  // buildings and their shadows
  const std::vector<cv::Vec3f> roofs{{60, 72, 158}, {122, 120, 118}, {74, 72, 70}, {196, 198, 204}};
  cv::Mat1b buildings(S, S, uint8_t(0));
  cv::Mat1f shadow(S, S, 0.f);
  std::vector<std::pair<std::vector<cv::Point>, cv::Vec3f>> drawn;
  for (int i = 0; i < 14; ++i) {
    const cv::Point2f c(60 + U(rng) * (S - 120), 60 + U(rng) * (S - 120));
    const float w = 28 + U(rng) * 50, h = 28 + U(rng) * 50, a = U(rng) * 90;
    cv::Point2f q[4];
    cv::RotatedRect(c, cv::Size2f(w, h), a).points(q);
    std::vector<cv::Point> poly(q, q + 4), swept;
    for (int k = 0; k < 4; ++k) swept.push_back(poly[k]), swept.emplace_back(cv::Point2f(q[k]) + sun_vec);
    std::vector<cv::Point> hull;
    cv::convexHull(swept, hull);
    cv::fillConvexPoly(shadow, hull, cv::Scalar(1), cv::LINE_AA);
    cv::fillConvexPoly(buildings, poly, cv::Scalar(255));
    drawn.emplace_back(poly, roofs[i % roofs.size()]);
  }
  cv::GaussianBlur(shadow, shadow, cv::Size(), 1.2);
  ShadowScene sc;
  cv::Mat3f lit = img.clone(), sh = img.clone();
  for (const auto& [poly, col] : drawn) {
    cv::fillConvexPoly(lit, poly, cv::Scalar(col[0], col[1], col[2]));
    cv::fillConvexPoly(sh, poly, cv::Scalar(col[0], col[1], col[2]));
  }
  for (int y = 0; y < S; ++y)
    for (int x = 0; x < S; ++x) {
      if (buildings(y, x)) continue;
      const float s = shadow(y, x);
      for (int c = 0; c < 3; ++c) sh(y, x)[c] *= 1 - s * (1 - ratio[c]);
    }
  cv::Mat3f noise(S, S);
  cv::randn(noise, 0, 2.5);
  lit += noise, sh += noise;
  lit.convertTo(sc.lit, CV_8UC3);
  sh.convertTo(sc.shadowed, CV_8UC3);
  cv::Mat1b core = (shadow > 0.98f) & ~buildings, any = (shadow > 0.02f) & ~buildings;
  cv::erode(core, sc.shadow_core, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  cv::dilate(any, sc.shadow_any, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  return sc;
}

ShadowOptions On() {  // the compensation is opt-in
  ShadowOptions o;
  o.enabled = true;
  return o;
}

// Blue-tinted shadows (a ratio other than synth-city's): the step is found,
// most of the shadow is relit, little else is touched, and the relit shadow
// has the lit scene's colours.
TEST(Shadows, FindsTheStepAndRelightsTheShadows) {
  const cv::Vec3f ratio(0.55f, 0.44f, 0.38f);
  for (unsigned seed : {1u, 2u}) {
    const ShadowScene sc = MakeScene(ratio, seed);
    ShadowCompensation info;
    cv::Mat1b mask;
    const cv::Mat out = CompensateShadows(sc.shadowed, On(), &info, &mask);
    ASSERT_TRUE(info.applied) << "seed " << seed << ": " << info.samples << " samples, " << info.votes << " votes";
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(info.log_step[c], std::log(ratio[c]), 0.1) << "seed " << seed << " channel " << c;
    const double core = cv::countNonZero(sc.shadow_core);
    const double found = cv::countNonZero(mask & sc.shadow_core);
    const double outside = cv::countNonZero(mask & ~sc.shadow_any);
    EXPECT_GT(found / core, 0.6) << "seed " << seed;                                  // recall in the shadows' cores
    EXPECT_LT(outside / std::max(1.0, double(cv::countNonZero(mask))), 0.15) << "seed " << seed;  // precision
    // the relit cores against the scene without shadows
    const cv::Scalar err = cv::mean(cv::abs(cv::Mat3f(out) - cv::Mat3f(sc.lit)), sc.shadow_core & mask);
    const cv::Scalar before = cv::mean(cv::abs(cv::Mat3f(sc.shadowed) - cv::Mat3f(sc.lit)), sc.shadow_core);
    for (int c = 0; c < 3; ++c) {
      EXPECT_LT(err[c], 10) << "seed " << seed << " channel " << c;
      EXPECT_GT(before[c], 30) << "the scene's shadows are real";
    }
  }
}

// Grey shadows (every channel by the same factor) cannot be told from dark
// materials by colour: left alone. So is a scene without shadows.
TEST(Shadows, GreyShadowsAndNoShadowsLeaveThePhotoAlone) {
  for (const cv::Vec3f& ratio : {cv::Vec3f(0.45f, 0.45f, 0.45f), cv::Vec3f(1, 1, 1)}) {
    const ShadowScene sc = MakeScene(ratio, 3);
    ShadowCompensation info;
    const cv::Mat out = CompensateShadows(sc.shadowed, On(), &info);
    EXPECT_FALSE(info.applied) << "ratio " << ratio[0] << ": step " << info.log_step << ", " << info.votes << " votes";
    EXPECT_EQ(out.data, sc.shadowed.data);  // the same pixels, not a copy
  }
}

TEST(Shadows, OptionsAndBadInput) {
  const ShadowScene sc = MakeScene({0.55f, 0.44f, 0.38f}, 1);
  ShadowCompensation info;
  EXPECT_EQ(CompensateShadows(sc.shadowed, {}, &info).data, sc.shadowed.data);  // off by default
  EXPECT_FALSE(info.applied);
  cv::Mat1b grey;
  cv::cvtColor(sc.shadowed, grey, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(CompensateShadows(grey, On()).data, grey.data);  // no colour, no step
  EXPECT_TRUE(CompensateShadows(cv::Mat()).empty());
  EXPECT_THROW(CompensateShadows(cv::Mat(32, 32, CV_16UC3, cv::Scalar::all(0))), Error);
  ShadowOptions bad;
  bad.grow_window = 4;
  EXPECT_THROW(CompensateShadows(sc.shadowed, bad), Error);
  bad = {};
  bad.max_fraction = 0;
  EXPECT_THROW(bad.Check(), Error);
}

}  // namespace
}  // namespace mvkp
