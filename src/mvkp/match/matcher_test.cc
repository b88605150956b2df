#include "mvkp/match/matcher.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

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

TEST(Outline, PlausibilityCheck) {
  EXPECT_TRUE(IsPlausibleOutline({cv::Point2f(0, 0), {100, 0}, {100, 100}, {0, 100}}));
  EXPECT_FALSE(IsPlausibleOutline({cv::Point2f(0, 0), {100, 100}, {100, 0}, {0, 100}}));  // bow-tie
  EXPECT_FALSE(IsPlausibleOutline({cv::Point2f(0, 0), {2, 0}, {2, 2}, {0, 2}}));          // tiny
}

}  // namespace
}  // namespace mvkp
