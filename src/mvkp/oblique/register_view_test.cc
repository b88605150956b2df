#include "mvkp/oblique/register_view.h"

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

// A camera 100 m above (cx, cy), looking 30 degrees off nadir to the north.
ViewPose Camera(double cx, double cy) {
  const double a = 30 * CV_PI / 180;
  // rows: image x = east; image y = down the view; optical axis down, tilted north
  const cv::Matx33d R(1, 0, 0, 0, -std::cos(a), -std::sin(a), 0, std::sin(a), -std::cos(a));
  ViewPose p;
  p.ok = true;
  p.R = R;
  p.centre_m = {cx, cy, 100};
  p.t = -(R * p.centre_m);
  p.camera = CameraMatrix(cv::Matx33d(800, 0, 320, 0, 800, 240, 0, 0, 1), R, p.t);
  return p;
}

// A view whose pairs were lifted through a stage 1 that put every point
// `shift` metres off, and whose camera the outlines replaced by the true one.
ViewRegistration View(double cx, double cy, cv::Vec2d shift, bool replaced) {
  ViewRegistration r;
  r.pose = Camera(cx, cy);
  r.outline.replaced = replaced;
  for (int i = 0; i < 40; ++i) {
    const cv::Point3d truth(cx - 30 + 1.5 * i, cy + 40 + 13 * std::sin(i * 0.7), 2.0 + (i % 3) * 3.0);
    const cv::Vec3d u = r.pose.camera * cv::Vec4d(truth.x, truth.y, truth.z, 1);
    NadirMatch m;
    m.view = cv::Point2f(float(u[0] / u[2]), float(u[1] / u[2]));
    r.matches.push_back(m);
    r.world.emplace_back(truth.x + shift[0], truth.y + shift[1], truth.z);
  }
  r.pose.inlier.assign(r.matches.size(), 1);
  return r;
}

// Two views corrected by the outlines give back the stage-1 shift, in depth
// pixels (columns east, rows south).
TEST(Stage1Correction, RecoversAStage1Shift) {
  const double res = 0.5;
  const cv::Vec2d shift(1.6, -0.9);  // metres east, north
  const std::vector<ViewRegistration> views = {View(100, -200, shift, true), View(180, -150, shift, true)};
  cv::Matx33d C;
  int inliers = 0;
  ASSERT_TRUE(Stage1Correction(views, res, &C, &inliers));
  EXPECT_EQ(inliers, 80);
  EXPECT_NEAR(C(0, 2), -shift[0] / res, 0.02);
  EXPECT_NEAR(C(1, 2), shift[1] / res, 0.02);  // north is -row
  EXPECT_NEAR(C(0, 0), 1.0, 1e-4);
  EXPECT_NEAR(C(0, 1), 0.0, 1e-4);
}

// One replaced view, or views whose camera was not replaced, are not enough:
// the correction is left to the views' agreement.
TEST(Stage1Correction, NeedsTwoReplacedViews) {
  const cv::Vec2d shift(1.6, -0.9);
  cv::Matx33d C = cv::Matx33d::eye();
  EXPECT_FALSE(Stage1Correction({View(100, -200, shift, true)}, 0.5, &C));
  EXPECT_FALSE(Stage1Correction({View(100, -200, shift, true), View(180, -150, shift, false)}, 0.5, &C));
  EXPECT_EQ(C, cv::Matx33d::eye());
  EXPECT_FALSE(Stage1Correction({}, 0.5, &C));
  EXPECT_THROW(Stage1Correction({}, 0, &C), Error);
  Stage1CorrectionOptions o;
  o.ransac_px = 0;
  EXPECT_THROW(Stage1Correction({}, 0.5, &C, nullptr, o), Error);
}

}  // namespace
}  // namespace mvkp
