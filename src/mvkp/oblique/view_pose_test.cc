#include "mvkp/oblique/view_pose.h"

#include <random>

#include <gtest/gtest.h>

#include "mvkp/city/synth_oblique.h"
#include "mvkp/core/error.h"

namespace mvkp {
namespace {

struct Scene {
  City city;
  ObliqueView view;
};

Scene MakeScene(const std::string& style, double tilt, std::uint64_t seed) {
  CityOptions o;
  o.width = o.height = 400;
  o.buildings = 16;
  o.style = style;
  Scene s{MakeCity(o, seed), {}};
  ObliqueOptions v;
  v.tilt_deg = tilt;
  v.azimuth_deg = 40;
  v.width = 480, v.height = 360;
  v.gsd_m = 0.3;
  v.target = {200, 200};
  s.view = RenderOblique(s.city, v, seed);
  return s;
}

// Lifting a nadir pixel through the true stage 1 (homography and lean)
// lands on the check point's world position: open ground exactly, roof
// corners (on the roof's edge) to within a metre.
TEST(ViewPose, LiftingUndoesTheLean) {
  const Scene s = MakeScene("dense", 45, 3);
  ASSERT_GT(cv::norm(s.city.lean), 0.04);  // the dense style's photo leans
  const double res = s.city.options.res_m;
  const NadirLifter lift(s.city.depth, res, s.city.photo_to_depth, s.city.lean * (1.0 / res));
  int ground = 0, roofs = 0, roofs_near = 0;
  for (const auto& c : s.view.checks) {
    cv::Point3d X;
    ASSERT_TRUE(lift.Lift(c.nadir_px, &X));
    const double e = cv::norm(X - c.world);
    if (c.building < 0) {
      EXPECT_LT(e, 0.3) << c.depth_px;
      ++ground;
    } else {
      ++roofs, roofs_near += e < 1.0;
    }
  }
  EXPECT_GE(ground, 20);
  EXPECT_GE(roofs, 5);
  EXPECT_GE(roofs_near, roofs * 7 / 10);
}

// From check points lifted through stage 1 plus as many random wrong pairs,
// the camera is found to within a pixel; from wrong pairs only, none.
TEST(ViewPose, CameraFromLiftedPairsAmongOutliers) {
  for (double tilt : {35.0, 55.0}) {
    const Scene s = MakeScene("suburb", tilt, 5);
    const double res = s.city.options.res_m;
    const NadirLifter lift(s.city.depth, res, s.city.photo_to_depth, s.city.lean * (1.0 / res));
    std::vector<cv::Point3d> X;
    std::vector<cv::Point2d> x;
    for (const auto& c : s.view.checks) {
      cv::Point3d w;
      if (lift.Lift(c.nadir_px, &w)) X.push_back(w), x.push_back(c.oblique_px);
    }
    ASSERT_GE(X.size(), 30u);
    std::mt19937_64 g(9);
    const size_t n = X.size();
    for (size_t i = 0; i < n; ++i)
      X.push_back(X[g() % n]), x.push_back(cv::Point2d(double(g() % 480), double(g() % 360)));
    const ViewPose p = EstimateViewPose(X, x, s.view.K);
    ASSERT_TRUE(p.ok) << p.reason;
    EXPECT_LT(CheckPointError(p.camera, s.view), 1.5) << "tilt " << tilt;
    EXPECT_LT(cv::norm(p.centre_m - s.view.centre_m), 3.0);
    // outliers only: no camera
    std::vector<cv::Point3d> Xw(X.begin() + long(n), X.end());
    std::vector<cv::Point2d> xw(x.begin() + long(n), x.end());
    const ViewPose q = EstimateViewPose(Xw, xw, s.view.K);
    EXPECT_FALSE(q.ok) << q.reason;
  }
}

// Pairs in one corner of the view: the camera they give is refused when the
// view's size is known (one of 16 cells, 3 needed), however well they agree.
TEST(ViewPose, OneClusterIsNotACamera) {
  const Scene s = MakeScene("suburb", 40, 5);
  const cv::Matx33d KR = s.view.K * s.view.R, KRi = KR.inv();
  std::vector<cv::Point3d> X;
  std::vector<cv::Point2d> x;
  std::mt19937_64 g(4);
  for (int i = 0; i < 40; ++i) {
    // a pixel within 50 px of (70, 60), back to the ground plane z = 0
    const cv::Point2d px(40 + double(g() % 60), 30 + double(g() % 60));
    const cv::Vec3d d = KRi * cv::Vec3d(px.x, px.y, 1);
    const double t = -s.view.centre_m[2] / d[2];
    X.emplace_back(s.view.centre_m[0] + t * d[0], s.view.centre_m[1] + t * d[1], 0.0);
    X.back().z += double(g() % 3);  // a little relief: not a planar degeneracy
    const cv::Vec3d p = s.view.camera * cv::Vec4d(X.back().x, X.back().y, X.back().z, 1);
    x.emplace_back(p[0] / p[2], p[1] / p[2]);
  }
  const ViewPose free = EstimateViewPose(X, x, s.view.K);
  EXPECT_TRUE(free.ok) << free.reason;
  const ViewPose p = EstimateViewPose(X, x, s.view.K, {}, cv::Size(480, 360));
  EXPECT_FALSE(p.ok);
  EXPECT_NE(p.reason.find("1 of the view's 4 x 4 cells"), std::string::npos) << p.reason;
}

TEST(ViewPose, GroundHomographyMapsGroundPoints) {
  const Scene s = MakeScene("classic", 40, 2);
  const double res = s.city.options.res_m;
  for (const auto& c : s.view.checks) {
    if (c.building >= 0) continue;
    const cv::Matx33d H = GroundHomography(s.view.camera, res, c.world.z);
    const cv::Vec3d p = H * cv::Vec3d(c.depth_px.x, c.depth_px.y, 1);
    EXPECT_NEAR(p[0] / p[2], c.oblique_px.x, 1e-6);
    EXPECT_NEAR(p[1] / p[2], c.oblique_px.y, 1e-6);
  }
}

// The height step around a lifted point: none inside a roof or on open
// ground, the wall's height within the radius of a roof edge, -1 off the
// raster.
TEST(ViewPose, HeightStepMarksRoofEdges) {
  cv::Mat1f d(60, 60, 10.f);
  d(cv::Rect(20, 20, 20, 20)).setTo(22.f);  // a 12 m block, columns and rows 20..39
  const NadirLifter lift(d, 0.5, cv::Matx33d::eye(), {0, 0});
  EXPECT_FLOAT_EQ(lift.HeightStep({30, 30}, 2), 0.f);    // roof middle
  EXPECT_FLOAT_EQ(lift.HeightStep({8, 8}, 2), 0.f);      // ground
  EXPECT_FLOAT_EQ(lift.HeightStep({21, 30}, 2), 12.f);   // just inside the edge
  EXPECT_FLOAT_EQ(lift.HeightStep({18, 30}, 2), 12.f);   // just outside
  EXPECT_FLOAT_EQ(lift.HeightStep({17, 30}, 2), 0.f);    // three cells out
  EXPECT_FLOAT_EQ(lift.HeightStep({17, 30}, 3), 12.f);   // within a larger radius
  EXPECT_FLOAT_EQ(lift.HeightStep({-5, 30}, 2), -1.f);   // off the raster
}

TEST(ViewPose, BadInputIsRefused) {
  cv::Mat1f d(10, 10, std::numeric_limits<float>::quiet_NaN());
  EXPECT_THROW(NadirLifter(d, 0.5, cv::Matx33d::eye(), {0, 0}), Error);  // no data
  d.setTo(1.f);
  EXPECT_THROW(NadirLifter(d, 0, cv::Matx33d::eye(), {0, 0}), Error);
  EXPECT_THROW(NadirLifter(d, 0.5, cv::Matx33d::zeros(), {0, 0}), Error);
  EXPECT_THROW(EstimateViewPose({cv::Point3d()}, {}, cv::Matx33d::eye()), Error);
  const ViewPose p = EstimateViewPose({cv::Point3d(), cv::Point3d(1, 0, 0)}, {{0, 0}, {1, 1}}, cv::Matx33d::eye());
  EXPECT_FALSE(p.ok);
}

}  // namespace
}  // namespace mvkp
