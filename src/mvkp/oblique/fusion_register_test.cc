// Method 2 (feature fusion) through ViewRegistrar, end to end on generated
// cities: right cameras or none, never a wrong one.
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/city/synth_oblique.h"
#include "mvkp/core/error.h"
#include "mvkp/oblique/register_view.h"

namespace mvkp {
namespace {

City MakeTown(const std::string& style, std::uint64_t seed) {
  CityOptions o;
  o.width = o.height = 400;
  o.buildings = 16;
  o.style = style;
  o.min_scale = o.max_scale = 0.8;
  return MakeCity(o, seed);
}

ObliqueView View(const City& c, double tilt, double azimuth, double gsd, std::uint64_t seed) {
  ObliqueOptions v;
  v.tilt_deg = tilt;
  v.azimuth_deg = azimuth;
  v.width = 800, v.height = 600;
  v.gsd_m = gsd;
  v.target = {200, 200};
  return RenderOblique(c, v, seed);
}

ViewRegistrarOptions Fusion() {
  ViewRegistrarOptions o;
  o.method = ViewMethod::kFusion;
  return o;
}

// Views of a town from four sides at 35-55 degrees: fusion finds cameras
// for some of them (measured: 3 of 4), each within 2 px of the truth, and
// refuses the rest.
TEST(FusionRegister, RightCamerasOrNone) {
  const City c = MakeTown("suburb", 4);
  const double res = c.options.res_m;
  const ViewRegistrar reg(c.depth, res, c.photo, c.photo_to_depth, c.lean * (1.0 / res), Fusion());
  EXPECT_EQ(reg.tiles(), 0u);  // fusion trains no tiles
  EXPECT_GT(reg.nadir_fusion().rois, 5);
  int found = 0;
  struct Case {
    double tilt, azimuth, gsd;
  };
  for (const Case& k : {Case{35, 20, 0.3}, Case{45, 110, 0.4}, Case{50, 200, 0.3}, Case{55, 290, 0.45}}) {
    const ObliqueView v = View(c, k.tilt, k.azimuth, k.gsd, 9);
    const ViewRegistration r = reg.Register(v.image, v.K);
    EXPECT_EQ(r.method, ViewMethod::kFusion);
    EXPECT_TRUE(r.fusion_ran);
    if (!r.pose.ok) continue;
    ++found;
    EXPECT_LT(CheckPointError(r.pose.camera, v), 2.0) << k.tilt << " " << k.azimuth << ": " << r.pose.reason;
    EXPECT_GE(r.refinement.inliers, Fusion().fusion_min_confirmed);
    EXPECT_GE(r.refinement.inliers, Fusion().fusion_min_confirmed_share * r.refinement.tried);
  }
  EXPECT_GE(found, 2);
}

// A view of another town gets no camera.
TEST(FusionRegister, OtherGroundGetsNoCamera) {
  const City a = MakeTown("civic", 6), b = MakeTown("civic", 7);
  const double res = a.options.res_m;
  const ViewRegistrar reg(a.depth, res, a.photo, a.photo_to_depth, a.lean * (1.0 / res), Fusion());
  for (double tilt : {40.0, 50.0}) {
    const ObliqueView v = View(b, tilt, 60, 0.35, 3);
    const ViewRegistration r = reg.Register(v.image, v.K);
    EXPECT_FALSE(r.pose.ok) << tilt << ": " << r.pose.reason;
  }
}

// Auto: MVKP answers when it can; fusion only runs for a view MVKP finds
// no camera for. A large view is registered at the working resolution.
TEST(FusionRegister, AutoRunsFusionOnlyWhenMvkpFindsNothing) {
  const City c = MakeTown("suburb", 4);
  const double res = c.options.res_m;
  ViewRegistrarOptions o;
  o.method = ViewMethod::kAuto;
  const ViewRegistrar reg(c.depth, res, c.photo, c.photo_to_depth, c.lean * (1.0 / res), o);
  EXPECT_GT(reg.tiles(), 0u);
  const ObliqueView v = View(c, 40, 20, 0.3, 9);
  const ViewRegistration r = reg.Register(v.image, v.K);
  ASSERT_TRUE(r.pose.ok) << r.pose.reason;
  EXPECT_EQ(r.method, ViewMethod::kMvkp);
  EXPECT_FALSE(r.fusion_ran);
  EXPECT_LT(CheckPointError(r.pose.camera, v), 2.0);
  EXPECT_EQ(r.working_scale, 1.0);
  // The same view 2.5 times larger (2000 x 1500) is registered at the
  // working resolution (1600 px) and answered in its own pixels: the true
  // camera scaled, within 2.5 px (1 px of the original view).
  cv::Mat big;
  cv::resize(v.image, big, cv::Size(), 2.5, 2.5, cv::INTER_CUBIC);
  const cv::Matx33d S(2.5, 0, 0.75, 0, 2.5, 0.75, 0, 0, 1);  // x' = 2.5 (x + 0.5) - 0.5
  const ViewRegistration rb = reg.Register(big, S * v.K);
  ASSERT_TRUE(rb.pose.ok) << rb.pose.reason;
  EXPECT_NEAR(rb.working_scale, 0.8, 1e-9);
  double err = 0;
  for (const ObliqueCheckPoint& c : v.checks) {
    const cv::Vec3d u = rb.pose.camera * cv::Vec4d(c.world.x, c.world.y, c.world.z, 1);
    const cv::Vec3d t = S * cv::Vec3d(c.oblique_px.x, c.oblique_px.y, 1);
    err += std::hypot(u[0] / u[2] - t[0], u[1] / u[2] - t[1]);
  }
  EXPECT_LT(err / double(v.checks.size()), 2.5);
  for (const NadirMatch& m : rb.matches) EXPECT_TRUE(m.view.x >= 0 && m.view.x < big.cols && m.view.y >= 0 && m.view.y < big.rows);
  // a featureless view: MVKP finds nothing, fusion runs and finds nothing
  const ViewRegistration none = reg.Register(cv::Mat(600, 800, CV_8UC3, cv::Scalar(90, 120, 100)), v.K);
  EXPECT_FALSE(none.pose.ok);
  EXPECT_TRUE(none.fusion_ran);
  EXPECT_NE(none.pose.reason.find("mvkp:"), std::string::npos) << none.pose.reason;
}

TEST(FusionRegister, RefusesBadOptions) {
  ViewRegistrarOptions o = Fusion();
  o.fusion_tilts = {95};
  EXPECT_THROW(o.Check(), Error);
  o = Fusion();
  o.fusion_radii.clear();
  EXPECT_THROW(o.Check(), Error);
  o = Fusion();
  o.fusion_min_confirmed = 0;
  EXPECT_THROW(o.Check(), Error);
  o = Fusion();
  o.fusion_min_confirmed_share = 1.5;
  EXPECT_THROW(o.Check(), Error);
  o = Fusion();
  o.max_view_px = 10;
  EXPECT_THROW(o.Check(), Error);
}

}  // namespace
}  // namespace mvkp
