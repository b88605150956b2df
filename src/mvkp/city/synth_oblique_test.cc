#include "mvkp/city/synth_oblique.h"

#include <cmath>

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

City SmallCity(const std::string& style, std::uint64_t seed) {
  CityOptions o;
  o.width = o.height = 360;
  o.buildings = 16;
  o.trees = 15;
  o.min_scale = o.max_scale = 1.0;
  o.style = style;
  return MakeCity(o, seed);
}

ObliqueOptions SmallView(double tilt, double azimuth) {
  ObliqueOptions o;
  o.tilt_deg = tilt;
  o.azimuth_deg = azimuth;
  o.width = 400, o.height = 300;
  o.gsd_m = 0.35;
  return o;
}

// The camera matrix and the rendering agree: the target is at the image
// centre, and every visible roof corner projects onto its own building
// (the renderer's id buffer, within 2 px).
TEST(SynthOblique, CameraMatrixAgreesWithTheRendering) {
  for (const char* style : {"classic", "dense"}) {
    const City city = SmallCity(style, 7);
    for (double tilt : {30.0, 55.0}) {
      ObliqueOptions o = SmallView(tilt, 70);
      o.target = {180, 180};
      const ObliqueView v = RenderOblique(city, o, 3);
      ASSERT_EQ(v.image.size(), cv::Size(400, 300));
      const double res = city.options.res_m;
      int roofs = 0, on_own = 0, ground = 0;
      for (const auto& c : v.checks) {
        const cv::Vec3d p = v.camera * cv::Vec4d(c.world.x, c.world.y, c.world.z, 1);
        EXPECT_NEAR(p[0] / p[2], c.oblique_px.x, 1e-6);
        EXPECT_NEAR(c.depth_px.x, c.world.x / res, 1e-9);
        EXPECT_NEAR(c.depth_px.y, -c.world.y / res, 1e-9);
        if (c.building < 0) {
          ++ground;
          continue;
        }
        ++roofs;
        bool found = false;
        for (int dy = -2; dy <= 2 && !found; ++dy)
          for (int dx = -2; dx <= 2 && !found; ++dx) {
            const int x = int(std::lround(c.oblique_px.x)) + dx, y = int(std::lround(c.oblique_px.y)) + dy;
            found = x >= 0 && y >= 0 && x < v.building_id.cols && y < v.building_id.rows &&
                    v.building_id(y, x) == c.building;
          }
        on_own += found;
      }
      EXPECT_GE(roofs, 4) << style << " tilt " << tilt;
      EXPECT_GE(ground, 20) << style << " tilt " << tilt;
      EXPECT_GE(on_own, roofs * 9 / 10) << style << " tilt " << tilt;
      // the camera looks down at the asked tilt, and is a proper rotation
      EXPECT_NEAR(std::acos(-v.R(2, 2)) * 180 / CV_PI, tilt, 1e-6);
      EXPECT_NEAR(cv::determinant(cv::Mat(v.R)), 1.0, 1e-9);
      // the evaluation's measure: 0 for the true camera, about 10 px for one 10 px to the side
      EXPECT_LT(CheckPointError(v.camera, v), 1e-6);
      cv::Matx34d off = v.camera;
      for (int j = 0; j < 4; ++j) off(0, j) += 10 * v.camera(2, j);  // x' = x + 10
      EXPECT_NEAR(CheckPointError(off, v), 10.0, 1e-6);
    }
  }
}

// A nadir view at the depth's resolution is the depth raster shifted (not
// mirrored, not rotated), up to the small scale change of the terrain's
// height at this distance.
TEST(SynthOblique, NadirViewMatchesTheTrueOrtho) {
  const City city = SmallCity("classic", 11);
  ObliqueOptions o = SmallView(0, 0);
  o.target = {180, 180};
  o.gsd_m = city.options.res_m;  // one view px per depth px at the centre
  const ObliqueView v = RenderOblique(city, o, 5);
  ASSERT_GE(v.checks.size(), 20u);
  // nadir, no roll: view px = depth px + constant (up to the perspective of
  // heights, small at this distance)
  for (const auto& c : v.checks) {
    if (c.building >= 0) continue;  // ground: no parallax
    const cv::Point2d d = c.oblique_px - c.depth_px;
    const cv::Point2d d0 = cv::Point2d(199.5, 149.5) - cv::Point2d(180, 180);  // the target at the centre
    EXPECT_LT(cv::norm(d - d0), 1.0 + 0.02 * cv::norm(c.depth_px - cv::Point2d(180, 180))) << c.depth_px;
  }
}

TEST(SynthOblique, BadOptionsAreRefused) {
  const City city = SmallCity("classic", 1);
  ObliqueOptions o = SmallView(80, 0);
  EXPECT_THROW(RenderOblique(city, o, 1), Error);
  o = SmallView(45, 0);
  o.gsd_m = 0;
  EXPECT_THROW(RenderOblique(city, o, 1), Error);
  o = SmallView(45, 0);
  o.width = 5;
  EXPECT_THROW(RenderOblique(city, o, 1), Error);
  o = SmallView(45, 0);
  o.gsd_m = 0.02;
  o.hfov_deg = 120;  // camera a few metres from the target: below the roofs
  EXPECT_THROW(RenderOblique(city, o, 1), Error);
}

}  // namespace
}  // namespace mvkp
