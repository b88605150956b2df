#include "mvkp/oblique/nadir_tiles.h"

#include <cstdio>

#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include "mvkp/city/synth_oblique.h"
#include "mvkp/core/error.h"
#include "mvkp/oblique/view_pose.h"

namespace mvkp {
namespace {

cv::Mat Grey(const cv::Mat& bgr) {
  cv::Mat g;
  cv::cvtColor(bgr, g, cv::COLOR_BGR2GRAY);
  return g;
}

// The camera of `view` from the tiles' matches lifted through the true stage
// 1, trying the scales in turn as register-view does; ok = false if none.
ViewPose Camera(const City& city, const NadirTiles& tiles, const ObliqueView& view) {
  const double res = city.options.res_m;
  const NadirLifter lift(city.depth, res, city.photo_to_depth, city.lean * (1.0 / res));
  ViewPose p;
  for (double scale : {1.0, 0.5, 0.3}) {
    std::vector<cv::Point3d> X;
    std::vector<cv::Point2d> x;
    for (const auto& m : tiles.Match(Grey(view.image), scale)) {
      cv::Point3d w;
      if (lift.Lift(cv::Point2d(m.nadir), &w)) X.push_back(w), x.emplace_back(m.view);
    }
    p = EstimateViewPose(X, x, view.K, {}, view.image.size());
    if (p.ok) break;
  }
  return p;
}

City MakeTown(std::uint64_t seed) {
  CityOptions o;
  o.width = o.height = 500;
  o.buildings = 20;
  o.style = "suburb";
  o.min_scale = o.max_scale = 0.9;  // a 0.45 m photo of 281 x 364 px: two tiles
  return MakeCity(o, seed);
}

ObliqueView View(const City& c, double tilt, double gsd, std::uint64_t seed) {
  ObliqueOptions v;
  v.tilt_deg = tilt;
  v.azimuth_deg = 130;
  v.width = 640, v.height = 480;
  v.gsd_m = gsd;
  v.target = {250, 250};
  return RenderOblique(c, v, seed);
}

// Five views 35-55 degrees off nadir, as coarse as the photo (0.5 m) down to
// three times finer (0.17 m): at least three get a camera within 3 px on the
// check points (roof corners and open ground) of the view. Measured: GCC's
// build 4 right, 0 wrong, 1 none; the sanitizer build (clang) 3 right, 1
// wrong (the 35-degree view, 8.7 px off), 1 none. Zero wrong answers is the
// issue's goal, not yet met (docs/oblique.md: one wrong camera per 36
// held-back views); here at most one camera may be off, and it is printed.
TEST(NadirTiles, FindTheCameraOfObliqueViews) {
  const City city = MakeTown(4);
  const NadirTiles tiles(Grey(city.photo));
  ASSERT_GE(tiles.size(), 2u) << city.photo.size();
  int right = 0, wrong = 0;
  for (const auto& [tilt, gsd] : {std::pair{35.0, 0.5}, std::pair{40.0, 0.2}, std::pair{45.0, 0.25},
                                  std::pair{50.0, 0.17}, std::pair{55.0, 0.3}}) {
    const ObliqueView v = View(city, tilt, gsd, 11);
    ASSERT_GE(v.checks.size(), 10u);
    const ViewPose p = Camera(city, tiles, v);
    if (!p.ok) continue;
    const double e = CheckPointError(p.camera, v);
    if (e < 3.0) {
      ++right;
    } else {
      ++wrong;
      std::printf("tilt %.0f gsd %.2f: camera %.1f px off\n", tilt, gsd, e);
    }
  }
  EXPECT_GE(right, 3);
  EXPECT_LE(wrong, 1);
}

// A view of another town: no camera, at any scale.
TEST(NadirTiles, NoCameraForOtherGround) {
  const City city = MakeTown(4), other = MakeTown(8);
  const NadirTiles tiles(Grey(city.photo));
  const ViewPose p = Camera(city, tiles, View(other, 40, 0.3, 3));
  EXPECT_FALSE(p.ok) << p.reason;
}

TEST(NadirTiles, BadInputIsRefused) {
  EXPECT_THROW(NadirTiles{cv::Mat()}, Error);
  EXPECT_THROW(NadirTiles{cv::Mat3b(100, 100)}, Error);  // not grey
  EXPECT_THROW(NadirTiles{cv::Mat1b(300, 300, uchar(128))}, Error);  // no texture anywhere
  NadirTilesOptions o;
  o.tile_px = 10;
  EXPECT_THROW((NadirTiles{cv::Mat1b(300, 300), o}), Error);
  o = {};
  o.stride = 0;
  EXPECT_THROW((NadirTiles{cv::Mat1b(300, 300), o}), Error);
}

}  // namespace
}  // namespace mvkp
