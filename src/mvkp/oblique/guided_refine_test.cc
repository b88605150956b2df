#include "mvkp/oblique/guided_refine.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/city/synth_oblique.h"
#include "mvkp/core/error.h"

namespace mvkp {
namespace {

struct Scene {
  City city;
  ObliqueView view;
  cv::Mat nadir, grey;
};

Scene MakeScene(const std::string& style, double tilt, double gsd, std::uint64_t seed) {
  CityOptions o;
  o.width = o.height = 400;
  o.buildings = 16;
  o.style = style;
  o.min_scale = o.max_scale = 0.8;  // a 0.4 m photo, as the evaluation's 0.2-0.9 m
  Scene s{MakeCity(o, seed), {}, {}, {}};
  ObliqueOptions v;
  v.tilt_deg = tilt;
  v.azimuth_deg = 40;
  v.width = 640, v.height = 480;
  v.gsd_m = gsd;
  v.target = {200, 200};
  s.view = RenderOblique(s.city, v, seed);
  cv::cvtColor(s.city.photo, s.nadir, cv::COLOR_BGR2GRAY);
  cv::cvtColor(s.view.image, s.grey, cv::COLOR_BGR2GRAY);
  return s;
}

// The true camera, its centre moved by `dc` metres and turned by `deg`.
ViewPose Perturbed(const ObliqueView& v, cv::Vec3d dc, double deg) {
  cv::Matx33d dR;
  cv::Rodrigues(cv::Vec3d(0.6, -0.8, 0) * (deg * CV_PI / 180), dR);
  ViewPose p;
  p.ok = true;
  p.R = dR * v.R;
  p.centre_m = v.centre_m + dc;
  p.t = -(p.R * p.centre_m);
  p.camera = CameraMatrix(v.K, p.R, p.t);
  return p;
}

// A camera a few pixels off (as from matches in one part of the view) is
// brought to within a pixel of the truth by the corners it predicts, in a
// fine and a coarse view (view px per nadir px above and below one).
TEST(GuidedRefine, BringsANearCameraToTheTruth) {
  struct Case {
    const char* style;
    double tilt, gsd;
  };
  for (const Case c : {Case{"suburb", 40, 0.2}, Case{"dense", 55, 0.5}}) {
    const Scene s = MakeScene(c.style, c.tilt, c.gsd, 7);
    const double res = s.city.options.res_m;
    const NadirLifter lift(s.city.depth, res, s.city.photo_to_depth, s.city.lean * (1.0 / res));
    const GuidedRefiner g(s.nadir, lift);
    ASSERT_GT(g.corners(), 200u);
    ViewPose p = Perturbed(s.view, {1.2, -0.9, 0.5}, 0.25);
    const double before = CheckPointError(p.camera, s.view);
    ASSERT_GT(before, 3.0) << c.style;  // a near miss to start from
    ASSERT_LT(before, 12.0) << c.style;
    const GuidedRefinement r = g.Refine(s.grey, s.view.K, lift, {}, {}, &p);
    ASSERT_TRUE(r.refined) << c.style << ": " << r.found << " of " << r.tried;
    const double after = CheckPointError(p.camera, s.view);
    EXPECT_LT(after, 1.0) << c.style << " from " << before;
    EXPECT_GE(r.inliers, 30);
    EXPECT_LT(r.rms_px, 1.0);
    EXPECT_LT(cv::norm(p.centre_m - s.view.centre_m), 1.0);
    EXPECT_NEAR(cv::norm(p.centre_m + p.R.t() * p.t), 0, 1e-6);  // centre and [R | t] agree
  }
}

// A camera far from the truth predicts corners where they are not: too few
// correlate, and the pose is left as it was (not walked to a local fit).
TEST(GuidedRefine, LeavesAFarCameraAlone) {
  const Scene s = MakeScene("suburb", 45, 0.3, 3);
  const double res = s.city.options.res_m;
  const NadirLifter lift(s.city.depth, res, s.city.photo_to_depth, s.city.lean * (1.0 / res));
  const GuidedRefiner g(s.nadir, lift);
  ViewPose p = Perturbed(s.view, {25, 18, 0}, 4);
  const cv::Matx34d first = p.camera;
  ASSERT_GT(CheckPointError(p.camera, s.view), 40.0);
  const GuidedRefinement r = g.Refine(s.grey, s.view.K, lift, {}, {}, &p);
  EXPECT_FALSE(r.refined) << r.found << " of " << r.tried;
  EXPECT_EQ(cv::norm(cv::Mat(p.camera), cv::Mat(first)), 0.0);
}

// The refit must keep the first camera's own inliers: pairs that a refit
// would contradict hold it back.
TEST(GuidedRefine, KeepsTheFirstCamerasInliers) {
  const Scene s = MakeScene("suburb", 40, 0.25, 7);
  const double res = s.city.options.res_m;
  const NadirLifter lift(s.city.depth, res, s.city.photo_to_depth, s.city.lean * (1.0 / res));
  const GuidedRefiner g(s.nadir, lift);
  ViewPose p = Perturbed(s.view, {1.0, -0.8, 0.4}, 0.2);
  // "inliers" of the first camera that the true one puts 15 px away (beyond
  // the 12 px a refit may move them)
  std::vector<cv::Point3d> X;
  std::vector<cv::Point2d> x;
  for (const auto& c : s.view.checks) X.push_back(c.world), x.push_back(c.oblique_px + cv::Point2d(0, 15));
  p.inlier.assign(X.size(), 1);
  const cv::Matx34d first = p.camera;
  const GuidedRefinement r = g.Refine(s.grey, s.view.K, lift, X, x, &p);
  EXPECT_FALSE(r.refined);
  EXPECT_EQ(cv::norm(cv::Mat(p.camera), cv::Mat(first)), 0.0);
}

TEST(GuidedRefine, WallsHideWhatIsBehindThem) {
  cv::Mat1f d(60, 60, 0.f);
  d(cv::Rect(20, 0, 4, 60)).setTo(10.f);  // a 10 m wall, columns 20..23
  const NadirLifter lift(d, 1.0, cv::Matx33d::eye(), {0, 0});
  const cv::Point3d behind(10, -30, 0);  // west of the wall, on the ground
  EXPECT_FALSE(lift.Visible(behind, {50, -30, 20}));   // camera east, low: the wall is in the way
  EXPECT_TRUE(lift.Visible(behind, {0, -30, 20}));     // camera west
  EXPECT_TRUE(lift.Visible(behind, {12, -30, 200}));   // nearly overhead
  EXPECT_TRUE(lift.Visible({21, -30, 10}, {50, -30, 20}));  // the wall's top
}

TEST(GuidedRefine, BadInputIsRefused) {
  GuidedRefineOptions o;
  o.min_ncc = 1.5;
  EXPECT_THROW(o.Check(), Error);
  cv::Mat1f d(40, 40, 0.f);
  const NadirLifter lift(d, 1.0, cv::Matx33d::eye(), {0, 0});
  EXPECT_THROW(GuidedRefiner(cv::Mat(), lift), Error);
  EXPECT_THROW(GuidedRefiner(cv::Mat3b(40, 40), lift), Error);
  const GuidedRefiner g(cv::Mat1b(40, 40, uchar(0)), lift);
  ViewPose p;
  EXPECT_THROW(g.Refine(cv::Mat(), cv::Matx33d::eye(), lift, {}, {}, &p), Error);
  EXPECT_FALSE(g.Refine(cv::Mat1b(40, 40, uchar(0)), cv::Matx33d::eye(), lift, {}, {}, &p).refined);  // no pose
}

}  // namespace
}  // namespace mvkp
