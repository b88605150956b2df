#include "mvkp/shapes/edge_evidence.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/shapes/register.h"

namespace mvkp {
namespace {

// A photo of roofs (filled polygons of random grey levels on textured ground,
// with distracting road lines) and the same roofs' outlines in depth px,
// related by `photo_to_depth`.
struct Scene {
  cv::Mat photo;
  std::vector<Contour> depth_outlines;
  cv::Matx33d photo_to_depth;
};

Scene MakeScene(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  Scene s;
  s.photo = cv::Mat(600, 800, CV_8UC3);
  cv::randn(s.photo, cv::Scalar(110, 115, 105), cv::Scalar(12, 12, 12));
  // Values are drawn one statement at a time: the arguments of one call are
  // evaluated in an order the compiler picks, and clang drew other scenes.
  for (int i = 0; i < 12; ++i) {  // roads and markings: edges that are not roofs
    const int thick = 3 + int(10 * U(rng));
    const double b2 = 70 + 100 * U(rng), b1 = 70 + 100 * U(rng), b0 = 70 + 100 * U(rng);
    const int y1 = int(U(rng) * 600), x1 = int(U(rng) * 800), y0 = int(U(rng) * 600), x0 = int(U(rng) * 800);
    cv::line(s.photo, cv::Point(x0, y0), cv::Point(x1, y1), cv::Scalar(b0, b1, b2), thick);
  }
  // photo -> depth: rotation 35 deg, scale 0.7, shift, mild perspective
  const double a = 35 * CV_PI / 180, sc = 0.7;
  s.photo_to_depth = cv::Matx33d(sc * std::cos(a), -sc * std::sin(a), 300, sc * std::sin(a), sc * std::cos(a), 40,
                                 2e-5, -1e-5, 1);
  std::vector<Contour> photo_roofs;
  for (int i = 0; i < 14; ++i) {
    const float cy = float(70 + 460 * U(rng)), cx = float(80 + 640 * U(rng));  // in this order, as above
    const cv::Point2f c(cx, cy);
    const float w = float(25 + 40 * U(rng)), h = float(20 + 35 * U(rng));
    Contour r = {c + cv::Point2f(-w, -h), c + cv::Point2f(w, -h), c + cv::Point2f(w, h), c + cv::Point2f(-w / 3, h),
                 c + cv::Point2f(-w / 3, h / 2), c + cv::Point2f(-w, h / 2)};
    std::vector<cv::Point> ip;
    for (const auto& p : r) ip.emplace_back(int(std::lround(p.x)), int(std::lround(p.y)));
    const double g = U(rng) < 0.5 ? 40 + 40 * U(rng) : 170 + 60 * U(rng);  // darker or brighter than the ground
    cv::fillPoly(s.photo, std::vector<std::vector<cv::Point>>{ip}, cv::Scalar(g, g, g + 10), cv::LINE_AA);
    photo_roofs.push_back(r);
  }
  cv::GaussianBlur(s.photo, s.photo, cv::Size(), 0.7);
  for (const auto& r : photo_roofs) s.depth_outlines.push_back(TransformPoints(s.photo_to_depth, r));
  return s;
}

double MaxCornerError(const cv::Matx33d& A, const cv::Matx33d& B) {
  double e = 0;
  for (cv::Point2f p : {cv::Point2f(100, 100), cv::Point2f(700, 100), cv::Point2f(700, 500), cv::Point2f(100, 500)})
    e = std::max(e, double(cv::norm(TransformPoints(A, {p})[0] - TransformPoints(B, {p})[0])));
  return e;
}

TEST(EdgeEvidence, RightTransformHasOutlinesOnEdgesWrongOnesDoNot) {
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const Scene s = MakeScene(seed);
    const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
    const EdgeScore right = ev.Evaluate(s.photo_to_depth);
    EXPECT_TRUE(right.enough);
    EXPECT_GE(right.contrast, 2.5) << "seed " << seed;
    EXPECT_TRUE(ev.Accepts(right));
    EXPECT_GE(right.regions, 10);
    EXPECT_GE(right.regions_on_edges, right.regions - 1);  // every roof outline on its edges
    // wrong: shifted by 25 depth px, rotated by 20 degrees, scaled by 1.3
    const double a = 20 * CV_PI / 180;
    for (const cv::Matx33d& C : {cv::Matx33d(1, 0, 25, 0, 1, -10, 0, 0, 1),
                                 cv::Matx33d(std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1),
                                 cv::Matx33d(1.3, 0, -60, 0, 1.3, -20, 0, 0, 1)}) {
      const EdgeScore wrong = ev.Evaluate(C * s.photo_to_depth);
      EXPECT_LT(wrong.contrast, 1.5) << "seed " << seed;
      EXPECT_FALSE(ev.Accepts(wrong));
      EXPECT_LT(wrong.regions_on_edges, wrong.regions / 2 + 1);
    }
  }
}

TEST(EdgeEvidence, PhotoScaleMapsContourPixelsToImagePixels) {
  const Scene s = MakeScene(4);
  cv::Mat half;
  cv::resize(s.photo, half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
  const EdgeEvidence ev(half, 0.5, s.depth_outlines);  // contours stay in full-photo px
  EXPECT_TRUE(ev.Accepts(ev.Evaluate(s.photo_to_depth)));
}

TEST(EdgeEvidence, RefineSnapsAnImpreciseTransformOntoTheEdges) {
  const Scene s = MakeScene(5);
  const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
  // about the middle of the outlines: 1 % scale, 0.5 degree, (2, -1.5) px
  const cv::Point2f c = TransformPoints(s.photo_to_depth, {cv::Point2f(400, 300)})[0];
  const double a = 0.5 * CV_PI / 180;
  const cv::Matx33d M(1.01 * std::cos(a), -1.01 * std::sin(a), 2, 1.01 * std::sin(a), 1.01 * std::cos(a), -1.5, 0, 0, 1);
  const cv::Matx33d off = cv::Matx33d(1, 0, c.x, 0, 1, c.y, 0, 0, 1) * M * cv::Matx33d(1, 0, -c.x, 0, 1, -c.y, 0, 0, 1) *
                          s.photo_to_depth;
  ASSERT_GT(MaxCornerError(off, s.photo_to_depth), 4.0);
  EXPECT_LT(MaxCornerError(ev.Refine(off, /*perspective=*/false), s.photo_to_depth), 1.0);
  const cv::Matx33d refined = ev.Refine(off, /*perspective=*/true);
  EXPECT_LT(MaxCornerError(refined, s.photo_to_depth), 1.0);
  EXPECT_GT(ev.Evaluate(refined).on, ev.Evaluate(off).on);
  // the right transform stays within a pixel of where it is
  EXPECT_LT(MaxCornerError(ev.Refine(s.photo_to_depth, true), s.photo_to_depth), 1.0);
}

// A transform right near some roofs but tilted (perspective) away from them:
// refining outwards from those roofs corrects the far ones too.
TEST(EdgeEvidence, RefineOutwardFixesExtrapolation) {
  const Scene s = MakeScene(9);
  const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
  // error growing with the distance from a seed corner of the depth extent
  cv::Rect2d all = cv::boundingRect(s.depth_outlines[0]);
  for (const auto& c : s.depth_outlines) all |= cv::Rect2d(cv::boundingRect(c));
  const cv::Rect2d seed(all.x, all.y, all.width * 0.35, all.height * 0.35);
  const std::vector<cv::Point2f> from = {cv::Point2f(float(all.x), float(all.y)), cv::Point2f(float(all.br().x), float(all.y)),
                                         cv::Point2f(float(all.br().x), float(all.br().y)), cv::Point2f(float(all.x), float(all.br().y))};
  std::vector<cv::Point2f> to = from;
  to[1] += cv::Point2f(3, 4), to[2] += cv::Point2f(-6, 7), to[3] += cv::Point2f(4, -3);
  const cv::Matx33d off = cv::Matx33d(cv::getPerspectiveTransform(from, to)) * s.photo_to_depth;
  ASSERT_GT(MaxCornerError(off, s.photo_to_depth), 4.0);
  const cv::Matx33d refined = ev.RefineOutward(off, seed, /*perspective=*/true);
  EXPECT_LT(MaxCornerError(refined, s.photo_to_depth), 1.5);
  const EdgeScore e = ev.Evaluate(refined);
  EXPECT_GE(e.regions_on_edges, e.regions - 1);
}

// A transform right near one corner of the roofs and 15-24 px off at the
// others (a scale, shear and perspective error, as a fit of a few nearby
// region pairs extrapolates): Relocate, measuring the error cell by cell,
// brings it back. (On these clean roofs Refine's basin is wide enough too;
// on generated towns shadows and neighbouring roofs trap it, issue 21.)
// From the right transform it does not move.
TEST(EdgeEvidence, RelocateRecoversATransformOffAwayFromItsRegions) {
  for (std::uint64_t seed : {11u, 12u}) {
    const Scene s = MakeScene(seed);
    const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
    cv::Rect2d all = cv::boundingRect(s.depth_outlines[0]);
    for (const auto& c : s.depth_outlines) all |= cv::Rect2d(cv::boundingRect(c));
    const std::vector<cv::Point2f> from = {cv::Point2f(float(all.x), float(all.y)),
                                           cv::Point2f(float(all.br().x), float(all.y)),
                                           cv::Point2f(float(all.br().x), float(all.br().y)),
                                           cv::Point2f(float(all.x), float(all.br().y))};
    std::vector<cv::Point2f> to = from;
    to[1] += cv::Point2f(16, 12), to[2] += cv::Point2f(-18, 16), to[3] += cv::Point2f(14, -15);
    const cv::Matx33d off = cv::Matx33d(cv::getPerspectiveTransform(from, to)) * s.photo_to_depth;
    ASSERT_GT(MaxCornerError(off, s.photo_to_depth), 15.0) << "seed " << seed;
    const EdgeEvidence::Relocation r = ev.Relocate(off, {}, /*perspective=*/true);
    EXPECT_TRUE(r.moved) << "seed " << seed;
    EXPECT_GE(r.rounds, 1);
    EXPECT_LT(MaxCornerError(r.photo_to_depth, s.photo_to_depth), 1.5) << "seed " << seed;
    EXPECT_GT(r.moved_px, 3.0);
    EXPECT_TRUE(ev.Accepts(r.edge));
    EXPECT_GE(r.edge.on, 1.05 * ev.Evaluate(off).on);
    // the right transform is kept
    const EdgeEvidence::Relocation k = ev.Relocate(s.photo_to_depth, {}, true);
    EXPECT_FALSE(k.moved) << "seed " << seed;
    EXPECT_LT(MaxCornerError(k.photo_to_depth, s.photo_to_depth), 1e-9);
    EXPECT_EQ(k.moved_px, 0.0);
    // off: relocate_rounds = 0
    EdgeEvidenceOptions o;
    o.relocate_rounds = 0;
    const EdgeEvidence no(s.photo, 1.0, s.depth_outlines, o);
    const EdgeEvidence::Relocation n = no.Relocate(off, {}, true);
    EXPECT_FALSE(n.moved);
    EXPECT_LT(MaxCornerError(n.photo_to_depth, off), 1e-9);
  }
}

// The footprint of a roof outline h metres high in a photo leaning by `lean`
// (depth px per metre): the roof shows h * lean from it.
Contour Footprint(const Contour& roof, float h, cv::Point2d lean) {
  Contour f;
  for (const auto& q : roof) f.push_back(q - cv::Point2f(float(lean.x * h), float(lean.y * h)));
  return f;
}

// A conventional orthophoto: each roof shows h * lean from its footprint.
// A transform fitted to the roofs carries the mean displacement; refining
// with the heights recovers the lean and the ground mapping.
TEST(EdgeEvidence, RefineEstimatesTheLeanOfAConventionalOrthophoto) {
  const Scene s = MakeScene(11);
  const cv::Point2d lean(0.30, -0.22);  // depth px per metre of height
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<float> heights;
  std::vector<Contour> footprints;
  double mean_h = 0;
  for (const auto& roof : s.depth_outlines) {
    const float h = float(5 + 35 * U(rng));
    heights.push_back(h);
    mean_h += h / double(s.depth_outlines.size());
    footprints.push_back(Footprint(roof, h, lean));
  }
  // the roof fit: the ground mapping shifted by the mean roof displacement
  const cv::Matx33d roof_fit = cv::Matx33d(1, 0, -mean_h * lean.x, 0, 1, -mean_h * lean.y, 0, 0, 1) * s.photo_to_depth;
  ASSERT_GT(MaxCornerError(roof_fit, s.photo_to_depth), 4.0);
  const EdgeEvidence ev(s.photo, 1.0, footprints, {}, heights);
  ASSERT_TRUE(ev.has_heights());
  // without the lean the refinement can only keep the mean roof
  EXPECT_GT(MaxCornerError(ev.Refine(roof_fit, false), s.photo_to_depth), 3.0);
  cv::Point2d est;
  const cv::Matx33d refined = ev.Refine(roof_fit, false, true, nullptr, &est);
  EXPECT_LT(MaxCornerError(refined, s.photo_to_depth), 1.0);
  EXPECT_NEAR(est.x, lean.x, 0.03);
  EXPECT_NEAR(est.y, lean.y, 0.03);
  EXPECT_GT(ev.Evaluate(refined, est).contrast, ev.Evaluate(roof_fit).contrast);
  // like heights: lean and translation are one move; no lean is claimed
  const EdgeEvidence flat(s.photo, 1.0, s.depth_outlines, {}, std::vector<float>(s.depth_outlines.size(), 15.f));
  cv::Point2d none;
  flat.Refine(s.photo_to_depth, false, true, nullptr, &none);
  EXPECT_EQ(none, cv::Point2d(0, 0));
  // heights must be one per outline
  EXPECT_THROW(EdgeEvidence(s.photo, 1.0, footprints, {}, std::vector<float>(3, 10.f)), Error);
}

// Relocate's lean jump: an answer refined at a wrong lean (a fit that
// traded lean for translation) is moved to the lean the roofs show and the
// right ground mapping; from the right answer it does not move; with
// relocate_lean_gain = 0 it is off.
TEST(EdgeEvidence, RelocateJumpsOutOfAWrongLean) {
  const Scene s = MakeScene(11);
  const cv::Point2d lean(0.30, -0.22);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<float> heights;
  std::vector<Contour> footprints;
  for (const auto& roof : s.depth_outlines) {
    const float h = float(5 + 35 * U(rng));
    heights.push_back(h);
    footprints.push_back(Footprint(roof, h, lean));
  }
  // the transform refined with the lean held at a wrong value
  EdgeEvidenceOptions held_lean;
  held_lean.max_lean_px_per_m = 0;
  const EdgeEvidence held(s.photo, 1.0, footprints, held_lean, heights);
  cv::Point2d wrong = lean + cv::Point2d(-0.45, -0.40);
  const cv::Matx33d trapped = held.Refine(s.photo_to_depth, false, true, nullptr, &wrong);
  ASSERT_GT(MaxCornerError(trapped, s.photo_to_depth), 3.0);
  EdgeEvidenceOptions o;
  o.relocate_rounds = 0;  // the lean jump alone
  const EdgeEvidence ev(s.photo, 1.0, footprints, o, heights);
  const EdgeEvidence::Relocation r = ev.Relocate(trapped, wrong, /*perspective=*/false);
  EXPECT_TRUE(r.moved);
  EXPECT_TRUE(r.lean_jumped);
  EXPECT_LT(MaxCornerError(r.photo_to_depth, s.photo_to_depth), 1.0);
  EXPECT_NEAR(r.lean.x, lean.x, 0.03);
  EXPECT_NEAR(r.lean.y, lean.y, 0.03);
  EXPECT_GE(r.edge.on, (1 + o.relocate_lean_gain) * ev.Evaluate(trapped, wrong).on);
  // from the right answer it stays
  const EdgeEvidence::Relocation k = ev.Relocate(s.photo_to_depth, lean, false);
  EXPECT_FALSE(k.moved);
  // off
  o.relocate_lean_gain = 0;
  const EdgeEvidence off(s.photo, 1.0, footprints, o, heights);
  EXPECT_FALSE(off.Relocate(trapped, wrong, false).moved);
  // without heights there is no lean to jump to
  const EdgeEvidence no_heights(s.photo, 1.0, footprints, EdgeEvidenceOptions{.relocate_rounds = 0});
  EXPECT_FALSE(no_heights.Relocate(trapped, wrong, false).lean_jumped);
}

// MeanGap: how far two transforms put the photo points on the outlines in
// view, in depth px; outlines out of view do not count.
TEST(EdgeEvidence, MeanGapMeasuresTwoAnswersWhereTheOutlinesAre) {
  cv::Mat1b photo(200, 200, uchar(0));
  const std::vector<Contour> outlines = {{{20, 20}, {60, 20}, {60, 60}, {20, 60}},
                                         {{500, 500}, {540, 500}, {540, 540}, {500, 540}}};  // out of view
  const EdgeEvidence ev(photo, 1.0, outlines);
  const cv::Matx33d I = cv::Matx33d::eye();
  EXPECT_NEAR(ev.MeanGap(I, I), 0, 1e-12);
  EXPECT_NEAR(ev.MeanGap(I, cv::Matx33d(1, 0, 3, 0, 1, 4, 0, 0, 1), 1), 5.0, 1e-9);
  // a scale about the square's centre moves its outline by 10 % of its distance from the centre
  const cv::Matx33d S(1.1, 0, -4, 0, 1.1, -4, 0, 0, 1);
  const double g = ev.MeanGap(I, S, 1);
  EXPECT_GT(g, 2.0);
  EXPECT_LT(g, 2.83);
  // nothing in view: 0
  EXPECT_EQ(ev.MeanGap(cv::Matx33d(1, 0, 1000, 0, 1, 1000, 0, 0, 1), I), 0);
  EXPECT_THROW(ev.MeanGap(I, I, 0), Error);
}

TEST(EdgeEvidence, NoVerdictWhenTheOutlinesMissThePhoto) {
  const Scene s = MakeScene(6);
  const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
  const EdgeScore away = ev.Evaluate(cv::Matx33d(1, 0, 5000, 0, 1, 5000, 0, 0, 1) * s.photo_to_depth);
  EXPECT_FALSE(away.enough);
  EXPECT_EQ(away.points, 0);
  EXPECT_FALSE(ev.Accepts(away));
  const EdgeEvidence none(s.photo, 1.0, {});
  EXPECT_FALSE(none.Evaluate(s.photo_to_depth).enough);
}

TEST(EdgeEvidence, RejectsBadInput) {
  const Scene s = MakeScene(7);
  EXPECT_THROW(EdgeEvidence(cv::Mat(), 1.0, s.depth_outlines), Error);
  EXPECT_THROW(EdgeEvidence(cv::Mat(10, 10, CV_32F, cv::Scalar(0)), 1.0, s.depth_outlines), Error);
  EXPECT_THROW(EdgeEvidence(s.photo, 0.0, s.depth_outlines), Error);
  EdgeEvidenceOptions o;
  o.offset_px = 1, o.search_px = 2;
  EXPECT_THROW(EdgeEvidence(s.photo, 1.0, s.depth_outlines, o), Error);
  EdgeEvidenceOptions r;
  r.roof_ring_px = 0;
  EXPECT_THROW(EdgeEvidence(s.photo, 1.0, s.depth_outlines, r), Error);
  for (int k = 0; k < 4; ++k) {
    EdgeEvidenceOptions q;
    if (k == 0) q.relocate_radius_px = 0;
    if (k == 1) q.relocate_grid_px = 2 * q.relocate_radius_px;
    if (k == 2) q.relocate_cells = 1;
    if (k == 3) q.relocate_rounds = -1;
    EXPECT_THROW(EdgeEvidence(s.photo, 1.0, s.depth_outlines, q), Error) << k;
  }
  cv::Mat grey;
  cv::cvtColor(s.photo, grey, cv::COLOR_BGR2GRAY);
  EXPECT_THROW(EdgeEvidence(grey, 1.0, s.depth_outlines, {}, {}, cv::Mat(3, 3, CV_8UC2)), Error);  // not its chroma
  EXPECT_THROW(EdgeEvidence::Chroma(grey), Error);
}

TEST(EdgeEvidence, ChromaIsTheLabChromaOfTheHalfSizePhoto) {
  // reference: OpenCV's 8-bit Lab of the same half-size image
  cv::Mat bgr(64, 96, CV_8UC3);
  cv::randu(bgr, cv::Scalar::all(0), cv::Scalar::all(256));
  const cv::Mat ab = EdgeEvidence::Chroma(bgr);
  ASSERT_EQ(ab.type(), CV_8UC2);
  ASSERT_EQ(ab.size(), cv::Size(48, 32));
  cv::Mat half, lab;
  cv::resize(bgr, half, ab.size(), 0, 0, cv::INTER_AREA);
  cv::cvtColor(half, lab, cv::COLOR_BGR2Lab);
  int worst = 0;
  for (int y = 0; y < ab.rows; ++y)
    for (int x = 0; x < ab.cols; ++x)
      for (int c = 0; c < 2; ++c)
        worst = std::max(worst, std::abs(int(ab.at<cv::Vec2b>(y, x)[c]) - int(lab.at<cv::Vec3b>(y, x)[c + 1])));
  EXPECT_LE(worst, 2);
}

// RegisterContours with image evidence: shapes alone accept from min_regions
// (4) region pairs; with outlines on photo edges 3 pairs suffice, and a photo
// without those edges does not lend that support.
TEST(EdgeEvidence, RegistrationUsesTheImageCheck) {
  const Scene s = MakeScene(8);
  std::vector<Contour> photo_regions;
  for (const auto& d : s.depth_outlines) photo_regions.push_back(TransformPoints(s.photo_to_depth.inv(), d));
  const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
  const Registration r = RegisterContours(photo_regions, s.depth_outlines, {}, &ev);
  ASSERT_TRUE(r.ok) << r.reason;
  EXPECT_LT(MaxCornerError(r.photo_to_depth, s.photo_to_depth), 1.0);
  EXPECT_TRUE(r.edge.enough);
  EXPECT_GE(r.edge.contrast, 2.5);

  // 3 regions: below min_regions, so only the image route can accept
  const std::vector<Contour> p3(photo_regions.begin(), photo_regions.begin() + 3);
  const std::vector<Contour> d3(s.depth_outlines.begin(), s.depth_outlines.begin() + 3);
  const EdgeEvidence ev3(s.photo, 1.0, d3);
  const Registration r3 = RegisterContours(p3, d3, {}, &ev3);
  ASSERT_TRUE(r3.ok) << r3.reason;
  // (a similarity fits 3 nearby roofs; the scene's perspective shows away from them)
  double err3 = 0;
  for (const auto& c : p3)
    for (const auto& p : c)
      err3 = std::max(err3, double(cv::norm(TransformPoints(r3.photo_to_depth, {p})[0] -
                                            TransformPoints(s.photo_to_depth, {p})[0])));
  EXPECT_LT(err3, 1.0);
  EXPECT_FALSE(RegisterContours(p3, d3, {}).ok);  // no image, no registration
  const cv::Mat blank(s.photo.size(), CV_8UC3, cv::Scalar(120, 120, 120));
  const EdgeEvidence flat(blank, 1.0, d3);
  const Registration r4 = RegisterContours(p3, d3, {}, &flat);
  EXPECT_FALSE(r4.ok);
  EXPECT_NE(r4.reason.find("image check"), std::string::npos) << r4.reason;
}

// A leaning orthophoto whose tall buildings stand on one side: the region
// pairs fitted without the lean carry a scale and tilt error as well as
// the mean roof displacement. Refitting the pairs with the lean
// (RegistrationOptions::joint_lean_fit) starts the lean refinement near the
// truth: the answer maps the ground within 2.5 px at the photo's corners
// and finds the lean (without: 5.6 px, the lean half found).
TEST(EdgeEvidence, RegistrationRefitsThePairsWithTheLean) {
  const Scene s = MakeScene(11);
  const cv::Point2d lean(0.30, -0.22);  // depth px per metre of height
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<float> heights;
  std::vector<Contour> footprints, photo_roofs;
  for (const auto& roof : s.depth_outlines) {
    cv::Point2f c(0, 0);
    for (const auto& q : roof) c += q * (1.f / float(roof.size()));
    // taller eastwards, and varied (heights exactly linear in position would
    // make the lean an affine map: the ground then cannot be told)
    const float h = std::clamp(5.f + 25.f * (c.x - 150.f) / 500.f + 10.f * float(U(rng)), 5.f, 40.f);
    heights.push_back(h);
    footprints.push_back(Footprint(roof, h, lean));
    photo_roofs.push_back(TransformPoints(s.photo_to_depth.inv(), roof));
  }
  const EdgeEvidence ev(s.photo, 1.0, footprints, {}, heights);
  RegistrationOptions with, without;
  without.joint_lean_fit = false;
  with.ambiguity_px = without.ambiguity_px = 0;  // (the lean's perturbations; this isolates the fit)
  // On this clean photo the two lean answers differ in edge contrast by 2 %,
  // under the default margin that guards real photos (joint_lean_gain): the
  // test takes the better one.
  with.joint_lean_gain = 0;
  const Registration r = RegisterContours(photo_roofs, footprints, with, &ev);
  ASSERT_TRUE(r.ok) << r.reason;
  // (the largest error at the photo's corners, outside the roofs' span)
  EXPECT_LT(MaxCornerError(r.photo_to_depth, s.photo_to_depth), 2.5);
  EXPECT_NEAR(r.lean_px_per_m.x, lean.x, 0.06);
  EXPECT_NEAR(r.lean_px_per_m.y, lean.y, 0.06);
  // from the lean-free fit alone the lean refinement stops short of it
  const Registration r0 = RegisterContours(photo_roofs, footprints, without, &ev);
  ASSERT_TRUE(r0.ok) << r0.reason;
  EXPECT_GT(MaxCornerError(r0.photo_to_depth, s.photo_to_depth), 3.5);
}

// A photo segmentation that found one roof: no consistent set of region
// pairs exists, but that pair's transform puts all 14 depth outlines on the
// photo's edges (the single-pair route). Without the photo's edges, or with
// the route off, no answer.
TEST(EdgeEvidence, SinglePairRouteRegistersOneRoofAmongManyOutlines) {
  const Scene s = MakeScene(12);
  const std::vector<Contour> one = {TransformPoints(s.photo_to_depth.inv(), s.depth_outlines[4])};
  const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
  const Registration r = RegisterContours(one, s.depth_outlines, {}, &ev);
  ASSERT_TRUE(r.ok) << r.reason;
  EXPECT_EQ(r.route, "single-pair");
  EXPECT_GE(r.route_confidence, 0.5);
  EXPECT_LT(MaxCornerError(r.photo_to_depth, s.photo_to_depth), 1.5);
  EXPECT_GE(r.edge.regions_on_edges, 10);
  RegistrationOptions off;
  off.single_pair_route = false;
  EXPECT_FALSE(RegisterContours(one, s.depth_outlines, off, &ev).ok);
  const cv::Mat blank(s.photo.size(), CV_8UC3, cv::Scalar(120, 120, 120));
  const EdgeEvidence flat(blank, 1.0, s.depth_outlines);
  const Registration r2 = RegisterContours(one, s.depth_outlines, {}, &flat);
  EXPECT_FALSE(r2.ok);
}

TEST(EdgeEvidence, RoofsStandApartAtTheRightTransformOnly) {
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const Scene s = MakeScene(seed);
    const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);
    EdgeScore right = ev.Evaluate(s.photo_to_depth);
    ev.ScoreRoofs(s.photo_to_depth, {}, &right);
    EXPECT_GE(right.roof_regions, 10) << "seed " << seed;
    EXPECT_GE(right.roof_contrast, 2.0) << "seed " << seed;
    EXPECT_TRUE(ev.Accepts(right));
    // far off: the outlines fall on ground and roads
    for (const cv::Matx33d& C : {cv::Matx33d(1, 0, 140, 0, 1, -90, 0, 0, 1), cv::Matx33d(1, 0, -120, 0, 1, 110, 0, 0, 1),
                                 cv::Matx33d(0.8, 0, 60, 0, 0.8, 50, 0, 0, 1)}) {
      const cv::Matx33d W = C * s.photo_to_depth;
      EdgeScore wrong = ev.Evaluate(W);
      ev.ScoreRoofs(W, {}, &wrong);
      EXPECT_GE(wrong.roof_regions, 4) << "seed " << seed;
      EXPECT_LT(wrong.roof_contrast, 0.9) << "seed " << seed;
      EXPECT_FALSE(ev.Accepts(wrong)) << "seed " << seed;
    }
  }
}

TEST(EdgeEvidence, RoofsDecideOnlyWhenScoredOverEnoughOutlines) {
  const Scene s = MakeScene(1);
  const EdgeEvidence ev(s.photo, 1.0, s.depth_outlines);  // defaults: edges 1.8; roofs over 4 outlines: 1.5 admits 1.5; over 2: veto 1.1
  EdgeScore e;
  e.enough = true;
  e.contrast = 1.6;
  EXPECT_FALSE(ev.Accepts(e));  // roofs not scored: the edges alone
  e.roof_regions = 6, e.roof_contrast = 2.0;
  EXPECT_TRUE(ev.Accepts(e));  // clear roofs admit an edge contrast of 1.6
  e.roof_contrast = 1.2;
  EXPECT_FALSE(ev.Accepts(e));
  e.roof_regions = 3, e.roof_contrast = 2.0;
  EXPECT_FALSE(ev.Accepts(e));  // too few outlines for a roof verdict
  e.contrast = 2.0, e.roof_regions = 6, e.roof_contrast = 0.5;
  EXPECT_FALSE(ev.Accepts(e));  // edges that pass, but no roofs where the outlines are: refused
  // (issue 21: a photo of other ground was registered with edges 2.04 and
  // roofs 0.93; no right answer with edges below 2.2 had roofs below 1.18)
  e.roof_contrast = 1.0;
  EXPECT_FALSE(ev.Accepts(e));
  e.roof_contrast = 1.15;
  EXPECT_TRUE(ev.Accepts(e));
  e.roof_contrast = 0.5;
  e.roof_regions = 3;
  EXPECT_FALSE(ev.Accepts(e));  // 3 outlines may refuse (min_roof_veto_regions), not admit
  e.roof_regions = 2;
  EXPECT_FALSE(ev.Accepts(e));  // ... and 2 (seed 130's photo of other ground: roofs 0.41 over 2)
  e.roof_regions = 1;
  EXPECT_TRUE(ev.Accepts(e));  // 1 outline: no roof verdict either way
  e.roof_regions = 6, e.contrast = 3.0;
  EXPECT_TRUE(ev.Accepts(e));  // decisive edges stand on their own
  e.enough = false, e.roof_regions = 6, e.roof_contrast = 3.0;
  EXPECT_FALSE(ev.Accepts(e));
  EdgeEvidenceOptions off;
  off.roof_veto = 0, off.roof_accept = 0;
  const EdgeEvidence ev_off(s.photo, 1.0, s.depth_outlines, off);
  EdgeScore f;
  f.enough = true, f.contrast = 3.0, f.roof_regions = 6, f.roof_contrast = 0.5;
  EXPECT_TRUE(ev_off.Accepts(f));
  f.contrast = 1.6, f.roof_contrast = 3.0;
  EXPECT_FALSE(ev_off.Accepts(f));
  // a grey photo: lightness only, the same verdicts at the right transform
  cv::Mat grey;
  cv::cvtColor(s.photo, grey, cv::COLOR_BGR2GRAY);
  const EdgeEvidence ev_grey(grey, 1.0, s.depth_outlines);
  EdgeScore g = ev_grey.Evaluate(s.photo_to_depth);
  ev_grey.ScoreRoofs(s.photo_to_depth, {}, &g);
  EXPECT_GE(g.roof_regions, 10);
  EXPECT_GE(g.roof_contrast, 2.0);
}

}  // namespace
}  // namespace mvkp
