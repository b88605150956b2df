#include "mvkp/shapes/shape_context.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace mvkp {
namespace {

// Dense closed polyline through the polygon's vertices (~1 px spacing).
Contour Densify(const Contour& poly, double step = 1.0) {
  Contour out;
  for (size_t i = 0; i < poly.size(); ++i) {
    const cv::Point2f a = poly[i], b = poly[(i + 1) % poly.size()];
    const int n = std::max(1, int(std::ceil(cv::norm(b - a) / step)));
    for (int k = 0; k < n; ++k) out.push_back(a + (b - a) * (float(k) / n));
  }
  return out;
}

Contour LShape() { return {{0, 0}, {80, 0}, {80, 25}, {30, 25}, {30, 60}, {0, 60}}; }

Contour Similar(const Contour& c, double deg, double s, cv::Point2f t) {
  const double a = deg * CV_PI / 180, ca = std::cos(a) * s, sa = std::sin(a) * s;
  Contour out;
  for (const auto& p : c) out.emplace_back(float(ca * p.x - sa * p.y + t.x), float(sa * p.x + ca * p.y + t.y));
  return out;
}

TEST(ShapeContext, ResampleIsUniformOrientedAndStartsAtMinY) {
  Contour sq = {{0, 0}, {0, 10}, {10, 10}, {10, 0}};  // negative orientation on input
  const Contour r = ResampleContour(Densify(sq), 40);
  ASSERT_EQ(r.size(), 40u);
  EXPECT_GT(SignedArea(r), 0);
  for (const auto& p : r) EXPECT_GE(p.y, r[0].y);
  for (int i = 0; i < 40; ++i) EXPECT_NEAR(cv::norm(r[(i + 1) % 40] - r[i]), 1.0, 1e-3);
  EXPECT_TRUE(ResampleContour({{0, 0}, {1, 1}}, 16).empty());
  EXPECT_TRUE(ResampleContour({{1, 1}, {1, 1}, {1, 1}}, 16).empty());
}

TEST(ShapeContext, InvariantToRotationScaleAndStartPoint) {
  ShapeContextOptions opt;
  const Contour base = Densify(LShape());
  const ShapeDescriptor a = DescribeContour(base, opt);
  ASSERT_FALSE(a.empty());
  ASSERT_EQ(a.hist.rows, opt.points);
  ASSERT_EQ(a.hist.cols, opt.radial_bins * opt.angular_bins);
  const double spacing = cv::arcLength(LShape(), true) / opt.points;
  for (double deg : {0.0, 37.0, 90.0, 180.0, 251.0})
    for (double s : {0.3, 1.0, 3.0})
      for (int start : {0, 17, 101}) {
        Contour c = Similar(Densify(LShape(), 0.5), deg, s, {500, -200});
        std::rotate(c.begin(), c.begin() + start % c.size(), c.end());
        const ShapeDescriptor b = DescribeContour(c, opt);
        ASSERT_FALSE(b.empty());
        const ShiftCost m = MatchDescriptors(a, b);
        EXPECT_LT(m.cost, 0.06) << deg << " deg, scale " << s;
        // the shift aligns the point lists: a_j mapped ~ b_(j+shift)
        const Contour pa = Similar(a.points, deg, s, {500, -200});
        double err = 0;
        for (int j = 0; j < opt.points; ++j) err += cv::norm(pa[j] - b.points[(j + m.shift) % opt.points]);
        EXPECT_LT(err / opt.points, 0.75 * spacing * s) << deg << " deg, scale " << s;
      }
}

TEST(ShapeContext, DistinguishesShapesAndAspect) {
  const ShapeDescriptor l = DescribeContour(Densify(LShape()));
  const ShapeDescriptor sq = DescribeContour(Densify({{0, 0}, {50, 0}, {50, 50}, {0, 50}}));
  const ShapeDescriptor rect = DescribeContour(Densify({{0, 0}, {120, 0}, {120, 30}, {0, 30}}));
  const ShapeDescriptor l2 = DescribeContour(Similar(Densify(LShape()), 200, 1.7, {3, 4}));
  const double same = MatchDescriptors(l, l2).cost;
  EXPECT_LT(same, MatchDescriptors(l, sq).cost * 0.5);
  EXPECT_LT(same, MatchDescriptors(l, rect).cost * 0.5);
  EXPECT_GT(MatchDescriptors(sq, rect).cost, 0.1);
}

TEST(ShapeContext, NoisyContourStillMatchesBest) {
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0, 1.5f);
  Contour c = Similar(Densify(LShape(), 2), 123, 1.0, {0, 0});
  for (auto& p : c) p += cv::Point2f(noise(rng), noise(rng));
  const ShapeDescriptor n = DescribeContour(c);
  const double to_l = MatchDescriptors(n, DescribeContour(Densify(LShape()))).cost;
  const double to_rect = MatchDescriptors(n, DescribeContour(Densify({{0, 0}, {80, 0}, {80, 60}, {0, 60}}))).cost;
  const double to_t = MatchDescriptors(
      n, DescribeContour(Densify({{0, 0}, {80, 0}, {80, 25}, {55, 25}, {55, 60}, {25, 60}, {25, 25}, {0, 25}}))).cost;
  EXPECT_LT(to_l, to_rect);
  EXPECT_LT(to_l, to_t);
}

TEST(ShapeContext, SymmetricShapeHasSeveralBestShifts) {
  const ShapeDescriptor a = DescribeContour(Densify({{0, 0}, {100, 0}, {100, 40}, {0, 40}}));
  const std::vector<ShiftCost> s = BestShifts(ShiftCosts(a, a), 4);
  ASSERT_GE(s.size(), 2u);
  EXPECT_NEAR(s[0].cost, 0.0, 1e-6);
  bool zero = false, half = false;
  for (const auto& x : s) zero = zero || x.shift == 0;
  EXPECT_TRUE(zero);
  for (const auto& x : s) half = half || std::abs(x.shift - a.hist.rows / 2) <= 1;
  EXPECT_TRUE(half);
}

TEST(ShapeContext, PartialDescriptorsMatchABrokenRegion) {
  // U shape (8 corners): the depth side gets partial descriptors; a photo
  // region that covers only one side of it matches a partial better than the whole.
  const Contour u = {{0, 0}, {90, 0}, {90, 70}, {60, 70}, {60, 25}, {30, 25}, {30, 70}, {0, 70}};
  EXPECT_EQ(CountCorners(Densify(u)), 8);
  const std::vector<ShapeDescriptor> parts = DescribePartials(Densify(u), {}, 6, 8);
  ASSERT_EQ(parts.size(), 8u);
  for (const auto& p : parts) EXPECT_TRUE(p.partial);
  const Contour broken = Similar(Densify({u[4], u[5], u[6], u[7], u[0]}), 77, 0.8, {10, 10});
  const ShapeDescriptor b = DescribeContour(broken);
  double best_part = 1;
  for (const auto& p : parts) best_part = std::min(best_part, MatchDescriptors(b, p).cost);
  EXPECT_LT(best_part, 0.05);
  EXPECT_LT(best_part, 0.5 * MatchDescriptors(b, DescribeContour(Densify(u))).cost);
  EXPECT_TRUE(DescribePartials(Densify({{0, 0}, {9, 0}, {9, 9}, {0, 9}})).empty());
}

}  // namespace
}  // namespace mvkp
