#include "mvkp/oblique/fusion.h"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/city/synth_city.h"
#include "mvkp/core/error.h"

namespace mvkp {
namespace {

cv::Mat Photo(const std::string& style, std::uint64_t seed) {
  CityOptions o;
  o.width = o.height = 400;
  o.buildings = 16;
  o.style = style;
  o.min_scale = o.max_scale = 0.8;
  return MakeCity(o, seed).photo;
}

cv::Point2f Apply(const cv::Matx23d& A, cv::Point2f p) {
  return {float(A(0, 0) * p.x + A(0, 1) * p.y + A(0, 2)), float(A(1, 0) * p.x + A(1, 1) * p.y + A(1, 2))};
}

// Both tracks are invariant to rotation and scale: the photo turned by 35
// degrees and shrunk to 0.75 is matched, and pairs of each track agree with
// the true similarity (the region track more: measured 30+ region pairs
// and 19-24 list pairs within 4 px); a similarity fitted to all the pairs
// is the true one within 4 px at the photo's corners (measured 2.6-3.0).
TEST(Fusion, MatchesARotatedScaledPhoto) {
  for (const char* style : {"classic", "suburb"}) {
    const cv::Mat photo = Photo(style, 5);
    const cv::Point2f c(photo.cols / 2.0f, photo.rows / 2.0f);
    cv::Matx23d A = cv::getRotationMatrix2D(c, 35, 0.75);
    A(0, 2) += 20, A(1, 2) -= 10;
    cv::Mat turned;
    cv::warpAffine(photo, turned, A, photo.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(90, 100, 95));
    const FusionFeatures fn = ExtractFusionFeatures(photo), fv = ExtractFusionFeatures(turned);
    ASSERT_GE(fn.rois, 5) << style;
    ASSERT_GE(fn.oels, 5) << style;
    FusionMatchStats st;
    const std::vector<NadirMatch> m = MatchFusion(fn, fv, {}, &st);
    int good_regions = 0, good_lists = 0;
    std::vector<cv::Point2f> from, to;
    for (const NadirMatch& p : m) {
      from.push_back(p.nadir), to.push_back(p.view);
      if (cv::norm(Apply(A, p.nadir) - p.view) > 4) continue;
      (p.tile < st.region_matches ? good_regions : good_lists)++;
    }
    EXPECT_GE(good_regions, 30) << style << ": " << st.region_matches << " region pairs";
    EXPECT_GE(good_lists, 10) << style << ": " << st.list_matches << " list pairs";
    std::vector<uchar> mask;
    const cv::Mat F = cv::estimateAffinePartial2D(from, to, mask, cv::RANSAC, 4.0, 5000, 0.999, 20);
    ASSERT_FALSE(F.empty()) << style;
    const cv::Matx23d Fm(F);
    for (const cv::Point2f q : {cv::Point2f(0, 0), cv::Point2f(float(photo.cols), 0), cv::Point2f(0, float(photo.rows)),
                                cv::Point2f(float(photo.cols), float(photo.rows))})
      EXPECT_LT(cv::norm(Apply(Fm, q) - Apply(A, q)), 4.0) << style;
  }
}

// Each ordered edgelet list is a chain: one edgelet ends where the next
// begins (within link_px), and every listed edgelet has a region label.
TEST(Fusion, ListsAreChainsOfLabelledEdgelets) {
  const cv::Mat photo = Photo("dense", 2);
  FusionOptions o;
  const FusionFeatures f = ExtractFusionFeatures(photo, o);
  ASSERT_GE(f.oels, 5);
  int links = 0;
  for (std::size_t i = 0; i < f.edgelets.size(); ++i) {
    EXPECT_GE(f.edgelets[i].label, 0);
    EXPECT_GE(f.edgelets[i].list, 0);
    if (i == 0 || f.edgelets[i].list != f.edgelets[i - 1].list) continue;
    EXPECT_LE(cv::norm(f.edgelets[i].a - f.edgelets[i - 1].b), o.link_px + 1e-3);
    ++links;
  }
  EXPECT_GE(links, 5 * (o.min_list_edgelets - 1));
}

// One camera, and feature pairs that are each self-consistent: three
// right ones (roof outlines at three heights, 1 px noise) and eight wrong
// ones, each seen by its own camera. The points of a wrong pair are as
// consistent as a right pair's, so a RANSAC over points could take any;
// the hypotheses count agreeing features, and the best is the truth.
TEST(FusionHypotheses, TheCameraMostFeaturesAgreeOn) {
  const cv::Matx33d K(900, 0, 511.5, 0, 900, 383.5, 0, 0, 1);
  auto camera = [&](double tilt_deg, cv::Vec3d centre) {
    const double a = tilt_deg * CV_PI / 180;
    const cv::Matx33d R(1, 0, 0, 0, -std::cos(a), -std::sin(a), 0, std::sin(a), -std::cos(a));
    return std::make_pair(R, cv::Vec3d(-(R * centre)));
  };
  const auto truth = camera(40, {500, -700, 150});
  cv::RNG rng(3);
  std::vector<cv::Point3d> world;
  std::vector<cv::Point2d> pixels;
  std::vector<int> pair_of, source;
  auto add = [&](const std::pair<cv::Matx33d, cv::Vec3d>& cam, cv::Point3d corner, int id) {
    for (int k = 0; k < 32; ++k) {  // a 20 x 12 m roof outline
      const double s = k / 32.0 * 64;
      const cv::Point3d X = corner + (s < 20 ? cv::Point3d(s, 0, 0) : s < 32 ? cv::Point3d(20, s - 20, 0)
                                      : s < 52 ? cv::Point3d(52 - s, 12, 0) : cv::Point3d(0, 64 - s, 0));
      const cv::Vec3d u = K * (cam.first * cv::Vec3d(X.x, X.y, X.z) + cam.second);
      world.push_back(X);
      pixels.emplace_back(u[0] / u[2] + rng.gaussian(1.0), u[1] / u[2] + rng.gaussian(1.0));
      pair_of.push_back(id);
    }
    source.push_back(id);
  };
  add(truth, {470, -620, 12}, 0);
  add(truth, {520, -600, 20}, 1);
  add(truth, {490, -580, 6}, 2);
  for (int w = 0; w < 8; ++w)
    add(camera(30 + 3 * w, {400 + 25.0 * w, -650 - 10.0 * w, 120 + 5.0 * w}), {430 + 12.0 * w, -640 + 9.0 * w, 8}, 3 + w);
  const std::vector<CameraHypothesis> h = FeatureHypotheses(world, pixels, pair_of, source, K, 20);
  ASSERT_FALSE(h.empty());
  EXPECT_EQ(h[0].features, 3);
  for (std::size_t i = 0; i < world.size(); ++i) EXPECT_EQ(bool(h[0].agree[i]), pair_of[i] < 3) << i;
  // its camera reprojects the right outlines within the noise
  double worst = 0;
  for (std::size_t i = 0; i < 96; ++i) {
    const cv::Vec3d u = K * (h[0].R * cv::Vec3d(world[i].x, world[i].y, world[i].z) + h[0].t);
    const cv::Vec3d v = K * (truth.first * cv::Vec3d(world[i].x, world[i].y, world[i].z) + truth.second);
    worst = std::max(worst, std::hypot(u[0] / u[2] - v[0] / v[2], u[1] / u[2] - v[1] / v[2]));
  }
  EXPECT_LT(worst, 1.5);
  for (std::size_t k = 1; k < h.size(); ++k) EXPECT_LE(h[k].features, 1) << k;
  EXPECT_THROW(FeatureHypotheses(world, pixels, pair_of, {0, 1}, K, 20), Error);  // pairs without a source
}

TEST(Fusion, RefusesBadInput) {
  EXPECT_THROW(ExtractFusionFeatures(cv::Mat()), Error);
  EXPECT_THROW(ExtractFusionFeatures(cv::Mat(50, 50, CV_16UC1, cv::Scalar(3))), Error);
  EXPECT_THROW(ExtractFusionFeatures(cv::Mat(50, 50, CV_8UC4, cv::Scalar(3))), Error);
  FusionOptions o;
  o.max_edgelet_px = o.min_edgelet_px;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.max_cost_ratio = 0;
  EXPECT_THROW(MatchFusion({}, {}, o), Error);
  // featureless images give no features and no pairs, not an error
  const FusionFeatures flat = ExtractFusionFeatures(cv::Mat(80, 80, CV_8UC3, cv::Scalar(120, 120, 120)));
  EXPECT_EQ(flat.rois, 0);
  EXPECT_TRUE(MatchFusion(flat, flat).empty());
}

}  // namespace
}  // namespace mvkp
