#include "mvkp/match/matcher.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/synth/camera_view.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/trainer.h"

namespace mvkp {
namespace {

cv::Mat Sample(const char* name, int flags = cv::IMREAD_GRAYSCALE) {
  cv::Mat m = cv::imread(std::string(MVKP_SOURCE_DIR) + "/samples/" + name, flags);
  EXPECT_FALSE(m.empty()) << name;
  return m;
}

class MatcherOnSyntheticViews : public ::testing::TestWithParam<const char*> {};

// Trains on a sample image and finds it in cluttered synthetic scenes with
// known homographies: most views must be located within 5 px.
TEST_P(MatcherOnSyntheticViews, FindsTheTargetWithin5px) {
  const cv::Mat target = PrepareTarget(Sample(GetParam()), 320);
  const Model model = Train(target, {});
  const Matcher matcher(model);
  SceneOptions so;
  int ok = 0;
  const int n = 12;
  for (int i = 0; i < n; ++i) {
    const SceneView v = MakeSceneView(target, so, 1000 + i);
    const MatchResult r = matcher.Match(v.image);
    if (r.found && MeanCornerError(r.homography, v.H, target.size()) < 5.0) ++ok;
  }
  EXPECT_GE(ok, n * 2 / 3) << GetParam();
}

INSTANTIATE_TEST_SUITE_P(Samples, MatcherOnSyntheticViews, ::testing::Values("starry_night.jpg", "astronaut.jpg"));

// The refinement's least-squares fit reaches the minimum cv::findHomography
// (method 0: DLT, then Levenberg-Marquardt) reaches: the same homography to
// a thousandth of a pixel on noisy pairs of a steep perspective view, from a
// start several pixels off; and refuses too few pairs.
TEST(FitHomographyLeastSquares, ReachesOpenCvsLeastSquaresMinimum) {
  cv::RNG rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const cv::Matx33d truth(0.8 + 0.1 * trial / 20.0, 0.15, 120, -0.05, 0.6, 80, 4e-4, -6e-4 * (trial % 3), 1);
    std::vector<cv::Point2f> src, dst;
    for (int i = 0; i < 30 + 10 * trial; ++i) {
      const cv::Point2f s(float(rng.uniform(0., 640.)), float(rng.uniform(0., 480.)));
      const cv::Vec3d p = truth * cv::Vec3d(s.x, s.y, 1);
      src.push_back(s);
      dst.emplace_back(float(p[0] / p[2] + rng.gaussian(1.0)), float(p[1] / p[2] + rng.gaussian(1.0)));
    }
    const cv::Matx33d cvH(cv::findHomography(src, dst, 0).ptr<double>());
    cv::Matx33d start = truth;
    start(0, 2) += 4;
    start(1, 2) -= 3;
    start(2, 0) *= 1.05;
    cv::Matx33d H;
    ASSERT_TRUE(FitHomographyLeastSquares(src, dst, start, H));
    EXPECT_LT(MeanCornerError(H, cvH, {640, 480}), 1e-3) << trial;
    EXPECT_NEAR(H(2, 2), 1.0, 1e-12);
  }
  std::vector<cv::Point2f> three = {{0, 0}, {1, 0}, {0, 1}};
  cv::Matx33d H = cv::Matx33d::eye();
  EXPECT_FALSE(FitHomographyLeastSquares(three, three, cv::Matx33d::eye(), H));
}

TEST(Matcher, SaysNotFoundOnAnUnrelatedImage) {
  const Model model = Train(PrepareTarget(Sample("starry_night.jpg"), 320), {});
  const Matcher matcher(model);
  for (const char* other : {"coffee.jpg", "fruits.jpg", "baboon.jpg"}) {
    const MatchResult r = matcher.Match(Sample(other));
    EXPECT_FALSE(r.found) << other << " inliers " << r.inliers;
  }
}

TEST(Matcher, AffineModeAndDynamicRatioWork) {
  const cv::Mat target = PrepareTarget(Sample("building.jpg"), 320);
  const Model model = Train(target, {});
  SceneOptions so;
  so.perspective = 0;
  const SceneView v = MakeSceneView(target, so, 77);
  MatchOptions mo;
  mo.geometry = GeometryModel::kAffine;
  const MatchResult r = Matcher(model, mo).Match(v.image);
  ASSERT_TRUE(r.found);
  EXPECT_LT(MeanCornerError(r.homography, v.H, target.size()), 5.0);
  EXPECT_EQ(r.homography(2, 0), 0.0);
  mo = MatchOptions{};
  mo.dynamic_goal = 40;
  const MatchResult d = Matcher(model, mo).Match(v.image);
  EXPECT_NE(d.final_ratio, mo.ratio);  // the ratio moved toward the goal
}

// Camera-model frames (synth/camera_view.h) on busy clutter: the envelope of
// issue 18, with a fixed pose per seed.
struct Envelope {
  cv::Mat target = Sample("starry_night.jpg");
  Model model = Train(target, {});
  Matcher matcher{model};
  cv::Mat photo = Sample("fruits.jpg", cv::IMREAD_COLOR);  // a real photo behind the target
  int Found(double size, double tilt, int n, std::uint64_t seed0, CameraSceneOptions o = {}, bool clutter = false) const {
    int ok = 0;
    for (int i = 0; i < n; ++i) {
      CameraPose p;
      p.size_px = size;
      p.tilt_deg = tilt;
      p.azimuth_deg = 47.0 * i;
      p.roll_deg = 71.0 * i;
      const std::uint64_t seed = seed0 + std::uint64_t(i);
      const cv::Mat bg = clutter ? MakeClutterBackground({o.width, o.height}, seed) : photo;
      const CameraScene s = MakeCameraScene(target, bg, p, o, seed);
      const MatchResult r = matcher.Match(s.image);
      ok += r.found && MeanCornerError(r.homography, s.H, target.size()) < 5.0;
    }
    return ok;
  }
};

const Envelope& Env() {
  static const Envelope e;
  return e;
}

TEST(MatcherEnvelope, TrainsAPyramidOfLevels) {
  const Model& m = Env().model;
  EXPECT_GE(m.params.levels, 3);  // 400 px: 400, 200, 100 (and 50)
  int per_level[8] = {0};
  for (const auto& l : m.locations) ++per_level[l.level];
  for (int k = 0; k < m.params.levels; ++k) EXPECT_GE(per_level[k], 4) << "level " << k;
  EXPECT_GT(per_level[0], per_level[1]);
}

TEST(MatcherEnvelope, FindsSmallTargets) {
  // 80 px across a 640x480 frame: below the thesis's trained scales (0.4 x 400 px).
  EXPECT_GE(Env().Found(80, 15, 6, 100), 3);
  EXPECT_GE(Env().Found(120, 15, 4, 150, {}, /*clutter=*/true), 2);
}

TEST(MatcherEnvelope, FindsSteepViews) {
  EXPECT_GE(Env().Found(300, 65, 5, 200), 3);
}

// At 72-79 degrees the full frame often gives a weak fit on the near part of
// the target whose far corners are off; the simulated tilts, tried for such
// weak steep fits too, put more of them within 5 px.
TEST(MatcherEnvelope, WeakSteepFitsAlsoTryTheSimulatedTilts) {
  const Envelope& e = Env();
  MatchOptions off;
  off.steep_anisotropy = 0;
  const Matcher without(e.model, off);
  int with_ok = 0, without_ok = 0;
  for (int i = 0; i < 16; ++i) {
    CameraPose p;
    p.size_px = 320;
    p.tilt_deg = 72 + 0.45 * i;
    p.azimuth_deg = 41.0 * i;
    p.roll_deg = 67.0 * i;
    const CameraScene s = MakeCameraScene(e.target, e.photo, p, {}, 700 + std::uint64_t(i));
    const MatchResult a = e.matcher.Match(s.image), b = without.Match(s.image);
    with_ok += a.found && MeanCornerError(a.homography, s.H, e.target.size()) < 5.0;
    without_ok += b.found && MeanCornerError(b.homography, s.H, e.target.size()) < 5.0;
  }
  // Deterministic frames: measured 11 of 16 against 9 without.
  EXPECT_GT(with_ok, without_ok);
  EXPECT_GE(with_ok, 10) << "without: " << without_ok;
}

TEST(MatcherEnvelope, FindsTargetsInLargeFramesInTheFramesPixels) {
  CameraSceneOptions o;
  o.width = 3000;
  o.height = 2250;
  o.supersample = 1;
  EXPECT_GE(Env().Found(1200, 20, 2, 300, o), 2);
  EXPECT_GE(Env().Found(400, 10, 2, 310, o), 1);  // 170 px at the working size
}

// Two passes: an easy frame is settled by the first, frame-spread half of the
// points (fewer matches searched, same answer); a frame the first pass cannot
// settle searches every point, as with first_pass_points = 0.
TEST(MatcherEnvelope, FirstPassSettlesEasyFramesAndFallsThroughOnHardOnes) {
  const Envelope& e = Env();
  MatchOptions all;
  all.first_pass_points = 0;
  const Matcher one_pass(e.model, all);
  CameraPose p;
  p.size_px = 380;
  p.tilt_deg = 20;
  p.roll_deg = 30;
  const CameraScene easy = MakeCameraScene(e.target, e.photo, p, {}, 500);
  const MatchResult a = e.matcher.Match(easy.image), b = one_pass.Match(easy.image);
  ASSERT_TRUE(a.found && b.found);
  EXPECT_LT(MeanCornerError(a.homography, easy.H, e.target.size()), 5.0);
  EXPECT_GE(a.inliers, e.matcher.options().retry_below_inliers);
  EXPECT_LT(a.matches.size(), b.matches.size());  // only the first pass was searched
  // Nothing to find: both passes run, so every point is searched.
  const cv::Mat clutter = MakeClutterBackground({640, 480}, 501);
  const MatchResult c = e.matcher.Match(clutter);
  EXPECT_FALSE(c.found);
  EXPECT_EQ(c.matches.size(), one_pass.Match(clutter).matches.size());
}

TEST(MatcherEnvelope, FindsNothingInClutter) {
  for (std::uint64_t seed = 400; seed < 404; ++seed) {
    const MatchResult r = Env().matcher.Match(MakeClutterBackground({640, 480}, seed));
    EXPECT_FALSE(r.found) << seed << ": " << r.inliers << " inliers";
  }
}

TEST(Outline, PlausibilityCheck) {
  EXPECT_TRUE(IsPlausibleOutline({cv::Point2f(0, 0), {100, 0}, {100, 100}, {0, 100}}));
  EXPECT_FALSE(IsPlausibleOutline({cv::Point2f(0, 0), {100, 100}, {100, 0}, {0, 100}}));  // bow-tie
  EXPECT_FALSE(IsPlausibleOutline({cv::Point2f(0, 0), {2, 0}, {2, 2}, {0, 2}}));          // tiny
}

}  // namespace
}  // namespace mvkp
