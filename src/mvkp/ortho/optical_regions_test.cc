#include "mvkp/ortho/optical_regions.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {
namespace {

// ---------------------------------------------------------------- synthetic city
enum class RoofKind { kFlat, kPitched, kL };

struct Roof {
  RoofKind kind;
  cv::Point2f centre;
  float w, h, angle;           // local rect sides, rotation (rad)
  cv::Vec3f colour;            // BGR base
};

struct Scene {
  cv::Mat3b photo;
  std::vector<cv::Mat1b> roof_masks;  // full footprints
  std::vector<RoofKind> kinds;
  cv::Mat1b tree_mask;                // visible tree pixels
};

// Local coordinates of pixel (x, y) in a roof frame.
cv::Point2f Local(const Roof& r, float x, float y) {
  const float c = std::cos(r.angle), s = std::sin(r.angle);
  const float dx = x - r.centre.x, dy = y - r.centre.y;
  return {c * dx + s * dy, -s * dx + c * dy};
}

bool Inside(const Roof& r, cv::Point2f l) {
  const bool main_rect = std::abs(l.x) <= r.w / 2 && std::abs(l.y) <= r.h / 2;
  if (r.kind != RoofKind::kL) return main_rect;
  // L: the main rect minus its upper-right quarter.
  return main_rect && !(l.x > 0 && l.y < -r.h * 0.05f);
}

cv::Mat1f Noise(cv::Size size, double sigma, int scale, cv::RNG& rng) {
  cv::Mat1f small((size.height + scale - 1) / scale + 1, (size.width + scale - 1) / scale + 1);
  rng.fill(small, cv::RNG::NORMAL, 0, sigma);
  cv::Mat1f big;
  cv::resize(small, big, cv::Size(small.cols * scale, small.rows * scale), 0, 0, cv::INTER_CUBIC);
  return big(cv::Rect(0, 0, size.width, size.height)).clone();
}

Scene MakeScene(unsigned seed, int size = 1000) {
  cv::RNG rng(seed);
  const cv::Size sz(size, size);
  // Ground: multi-scale grass texture (fBm-like), asphalt roads.
  // Drawn in a fixed order: the operands of one sum (like the arguments of one
  // call) are evaluated in an order the compiler picks, so clang drew other scenes.
  const cv::Mat1f t3 = Noise(sz, 7, 2, rng), t2 = Noise(sz, 8, 8, rng), t1 = Noise(sz, 10, 32, rng);
  cv::Mat1f tex = t1 + t2 + t3;
  cv::Mat3f img(sz);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const float t = tex(y, x);
      img(y, x) = cv::Vec3f(55 + 0.6f * t, 115 + t, 75 + 0.8f * t);
    }
  const int road = size * 2 / 5, rw = 30;
  cv::Mat1f asph = Noise(sz, 4, 2, rng);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x)
      if (std::abs(x - road) < rw / 2 || std::abs(y - size / 2) < rw / 2) {
        const float a = 95 + asph(y, x);
        img(y, x) = cv::Vec3f(a + 4, a, a - 2);
      }

  // Bare-soil patches: brown, textured like the grass (natural, fBm-like).
  for (int k = 0; k < 6; ++k) {
    const int cy = rng.uniform(0, size), cx = rng.uniform(0, size);
    const cv::Point c(cx, cy);  // fixed order, as above
    const int rad = rng.uniform(30, 60);
    std::vector<cv::Point> blob;
    for (int j = 0; j < 16; ++j) {
      const double a = j * std::numbers::pi / 8, rr = rad * rng.uniform(0.6, 1.2);
      blob.emplace_back(c.x + cvRound(rr * std::cos(a)), c.y + cvRound(rr * std::sin(a)));
    }
    cv::Mat1b bm(sz, 0);
    cv::fillPoly(bm, std::vector<std::vector<cv::Point>>{blob}, 255);
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x)
        if (bm(y, x)) {
          const float t = tex(y, x);
          img(y, x) = cv::Vec3f(75 + 0.7f * t, 105 + 0.9f * t, 135 + t);
        }
  }

  // Roofs in a 5 x 4 lot grid (lots clear of the roads).
  std::vector<Roof> roofs;
  const int lw = size / 5, lh = size / 4;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 5; ++i) {
      Roof r;
      const int n = j * 5 + i;
      r.kind = n % 3 == 0 ? RoofKind::kFlat : n % 3 == 1 ? RoofKind::kPitched : RoofKind::kL;
      const bool rotated = n % 4 == 3;
      const float maxw = rotated ? 0.45f * lw : 0.6f * lw, maxh = rotated ? 0.4f * lh : 0.55f * lh;
      r.w = static_cast<float>(rng.uniform(0.3 * lw, double(maxw)));
      r.h = static_cast<float>(rng.uniform(0.25 * lh, double(maxh)));
      r.angle = rotated ? static_cast<float>(rng.uniform(0.25, 0.6)) : 0.f;
      // Lots next to the roads keep clear of them.
      float cx = lw * (i + 0.5f), cy = lh * (j + 0.5f);
      cx += static_cast<float>(rng.uniform(-8.0, 8.0));
      cy += static_cast<float>(rng.uniform(-8.0, 8.0));
      r.centre = {cx, cy};
      if (r.kind == RoofKind::kPitched && n % 2 == 0) {  // slate
        const float g = static_cast<float>(rng.uniform(105, 125));
        r.colour = cv::Vec3f(g + 6, g, g - 4);
      } else if (r.kind == RoofKind::kPitched) {  // red tiles
        const float r2 = static_cast<float>(rng.uniform(160, 200)), r1 = static_cast<float>(rng.uniform(65, 90)),
                    r0 = static_cast<float>(rng.uniform(45, 70));  // fixed order, as above
        r.colour = cv::Vec3f(r0, r1, r2);
      } else {
        const float g = static_cast<float>(rng.uniform(135, 195));
        const float tint = static_cast<float>(rng.uniform(-8, 8));
        r.colour = cv::Vec3f(g + tint, g, g - tint);
      }
      roofs.push_back(r);
    }

  // Roof masks and texture.
  Scene sc;
  cv::Mat1b all_roofs(sz, 0);
  cv::Mat3f roof_img(sz, cv::Vec3f(0, 0, 0));
  cv::Mat1f fine = Noise(sz, 5, 1, rng);
  for (const Roof& r : roofs) {
    cv::Mat1b mk(sz, 0);
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) {
        const cv::Point2f l = Local(r, float(x), float(y));
        if (!Inside(r, l)) continue;
        mk(y, x) = 255;
        cv::Vec3f c = r.colour;
        if (r.kind == RoofKind::kPitched) {
          // Ridge along the long axis; the two halves lit differently; tile rows.
          const bool along_x = r.w >= r.h;
          const float across = along_x ? l.y : l.x, along = along_x ? l.x : l.y;
          const float shade = across < 0 ? 1.0f : 0.7f;
          const float tile = (static_cast<int>(std::floor(along / 5.f)) % 2 == 0) ? 1.0f : 0.9f;
          c *= shade * tile;
          c += cv::Vec3f(1, 1, 1) * (0.4f * fine(y, x));
        } else {
          c += cv::Vec3f(1, 1, 1) * fine(y, x);  // gravel
        }
        roof_img(y, x) = c;
      }
    sc.roof_masks.push_back(mk);
    sc.kinds.push_back(r.kind);
    all_roofs |= mk;
  }

  // Trees: noisy green blobs, half of them over roof corners.
  cv::Mat1b trees(sz, 0);
  cv::Mat1f leaf = Noise(sz, 22, 3, rng) + Noise(sz, 10, 1, rng);
  for (int t = 0; t < 26; ++t) {
    cv::Point c;
    const int rad = rng.uniform(12, 30);
    if (t % 2 == 0) {
      const Roof& r = roofs[(t * 7) % roofs.size()];
      const float sx = (t % 4 == 0) ? 1.f : -1.f;
      const float ca = std::cos(r.angle), sa = std::sin(r.angle);
      const float lx = sx * r.w / 2, ly = r.h / 2;
      c = cv::Point(cvRound(r.centre.x + ca * lx - sa * ly), cvRound(r.centre.y + sa * lx + ca * ly));
    } else {
      const int cy = rng.uniform(0, size), cx = rng.uniform(0, size);  // fixed order, as above
      c = cv::Point(cx, cy);
    }
    std::vector<cv::Point> blob;
    for (int k = 0; k < 24; ++k) {
      const double a = k * std::numbers::pi / 12, rr = rad * rng.uniform(0.75, 1.15);
      blob.emplace_back(c.x + cvRound(rr * std::cos(a)), c.y + cvRound(rr * std::sin(a)));
    }
    cv::fillPoly(trees, std::vector<std::vector<cv::Point>>{blob}, 255);
  }

  // Cast shadows (sun from the upper left): shifted roofs and trees, on the ground only.
  cv::Mat1b casters = all_roofs | trees, shadow;
  cv::warpAffine(casters, shadow, cv::Matx23f(1, 0, 9, 0, 1, 7), sz, cv::INTER_NEAREST);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      if (shadow(y, x) && !all_roofs(y, x)) img(y, x) *= 0.35f;
      if (all_roofs(y, x)) img(y, x) = roof_img(y, x);
      if (trees(y, x)) {
        const float v = leaf(y, x);
        img(y, x) = cv::Vec3f(35 + 0.4f * v, 95 + v, 50 + 0.6f * v);
      }
    }
  // Sensor noise and blur.
  cv::Mat3f noise(sz);
  rng.fill(noise, cv::RNG::NORMAL, 0, 6);
  img += noise;
  cv::GaussianBlur(img, img, cv::Size(), 0.7);
  img.convertTo(sc.photo, CV_8U);
  sc.tree_mask = trees & ~all_roofs;
  return sc;
}

cv::Mat1b RegionMask(const PhotoRegion& r, cv::Size sz) {
  cv::Mat1b m(sz, 0);
  cv::fillPoly(m, std::vector<std::vector<cv::Point>>{r.contour}, 255);
  return m;
}

double Iou(const cv::Mat1b& a, const cv::Mat1b& b) {
  const double i = cv::countNonZero(a & b), u = cv::countNonZero(a | b);
  return u > 0 ? i / u : 0;
}

double Shoelace(const std::vector<cv::Point>& c) {
  double s = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    const cv::Point a = c[i], b = c[(i + 1) % c.size()];
    s += double(a.x) * b.y - double(b.x) * a.y;
  }
  return 0.5 * s;
}

std::string DataDir() { return std::string(MVKP_SOURCE_DIR) + "/../shared/data"; }

// ---------------------------------------------------------------- tests

TEST(OpticalRegions, SyntheticCity) {
  const Scene sc = MakeScene(1);
  const cv::Size sz = sc.photo.size();
  SegmentOptical(sc.photo);  // warm-up (DefaultRegionLda training, page faults)
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);  // the time quoted is single-threaded
  Timer timer;
  cv::Mat1i labels;
  const std::vector<PhotoRegion> regions = SegmentOptical(sc.photo, {}, &labels);
  const double ms = timer.ElapsedMs();
  cv::setNumThreads(threads);
  cv::imwrite("/tmp/mvkp_ortho_synth.png", DrawPhotoRegions(sc.photo, regions));
  cv::imwrite("/tmp/mvkp_ortho_synth_maps.png", DrawOpticalMaps(sc.photo));

  cv::Mat1b gt_all(sz, 0);
  for (auto& m : sc.roof_masks) gt_all |= m;
  std::vector<cv::Mat1b> masks;
  for (auto& r : regions) masks.push_back(RegionMask(r, sz));

  int found = 0, pitched = 0, pitched_merged = 0;
  for (size_t g = 0; g < sc.roof_masks.size(); ++g) {
    double best = 0;
    for (auto& m : masks) best = std::max(best, Iou(m, sc.roof_masks[g]));
    found += best >= 0.5;
    if (sc.kinds[g] == RoofKind::kPitched) {
      ++pitched;
      pitched_merged += best >= 0.7;  // one half alone reaches IoU <= ~0.5
    }
  }
  int false_regions = 0, tree_regions = 0;
  for (size_t i = 0; i < regions.size(); ++i) {
    const double a = cv::countNonZero(masks[i]);
    if (cv::countNonZero(masks[i] & gt_all) < 0.5 * a) ++false_regions;
    if (cv::countNonZero(masks[i] & sc.tree_mask) >= 0.5 * a) ++tree_regions;
    // CCW on screen: negative shoelace in image coordinates; starts at the smallest y.
    EXPECT_LT(Shoelace(regions[i].contour), 0) << i;
    EXPECT_GE(regions[i].confidence, 0);
    EXPECT_LE(regions[i].confidence, 1);
    for (auto& p : regions[i].contour) EXPECT_GE(p.y, regions[i].contour[0].y);
  }
  const int n_roofs = static_cast<int>(sc.roof_masks.size());
  std::printf("[ortho] synthetic 1000x1000: %d/%d roofs found (%.0f %%), pitched merged %d/%d, "
              "%zu regions, %d false (%.0f %%), %d on trees, %.1f ms\n",
              found, n_roofs, 100.0 * found / n_roofs, pitched_merged, pitched, regions.size(),
              false_regions, regions.empty() ? 0.0 : 100.0 * false_regions / regions.size(),
              tree_regions, ms);
  EXPECT_GE(found, 0.7 * n_roofs);
  EXPECT_LE(false_regions, 0.2 * regions.size());
  EXPECT_GE(pitched_merged, 0.6 * pitched);
  EXPECT_EQ(tree_regions, 0);
  // labels agree with the regions.
  ASSERT_FALSE(regions.empty());
  const cv::Point c = regions[0].contour[0];
  EXPECT_GE(labels.at<int>(c), 1);
}

TEST(OpticalRegions, OtherSeedsAndSpeed) {
  int found = 0, total = 0, false_regions = 0, regions_total = 0;
  for (unsigned seed : {2u, 3u}) {
    const Scene sc = MakeScene(seed);
    const cv::Size sz = sc.photo.size();
    Timer timer;
    const auto regions = SegmentOptical(sc.photo);
    std::printf("[ortho] seed %u: %zu regions in %.1f ms\n", seed, regions.size(), timer.ElapsedMs());
    cv::Mat1b gt_all(sz, 0);
    for (auto& m : sc.roof_masks) gt_all |= m;
    std::vector<cv::Mat1b> masks;
    for (auto& r : regions) masks.push_back(RegionMask(r, sz));
    for (auto& g : sc.roof_masks) {
      double best = 0;
      for (auto& m : masks) best = std::max(best, Iou(m, g));
      found += best >= 0.5;
      ++total;
    }
    for (auto& m : masks) false_regions += cv::countNonZero(m & gt_all) < 0.5 * cv::countNonZero(m);
    regions_total += static_cast<int>(regions.size());
  }
  std::printf("[ortho] seeds 2,3: %d/%d roofs found, %d/%d false regions\n", found, total, false_regions,
              regions_total);
  EXPECT_GE(found, 0.7 * total);
  EXPECT_LE(false_regions, 0.2 * regions_total);
}

// Roof-finding score of one segmentation of a scene.
struct Score {
  int found = 0, pitched_merged = 0, false_regions = 0, regions = 0;
};

Score Evaluate(const Scene& sc, const std::vector<PhotoRegion>& regions) {
  Score s;
  cv::Mat1b gt_all(sc.photo.size(), 0);
  for (auto& m : sc.roof_masks) gt_all |= m;
  std::vector<cv::Mat1b> masks;
  for (auto& r : regions) masks.push_back(RegionMask(r, sc.photo.size()));
  for (size_t g = 0; g < sc.roof_masks.size(); ++g) {
    double best = 0;
    for (auto& m : masks) best = std::max(best, Iou(m, sc.roof_masks[g]));
    s.found += best >= 0.5;
    s.pitched_merged += sc.kinds[g] == RoofKind::kPitched && best >= 0.7;
  }
  for (auto& m : masks) s.false_regions += cv::countNonZero(m & gt_all) < 0.5 * cv::countNonZero(m);
  s.regions = static_cast<int>(regions.size());
  return s;
}

TEST(OpticalRegions, MergingJoinsPitchedRoofHalves) {
  // A dynamic intensity range too short to span both lit and shaded halves.
  const Scene sc = MakeScene(1);
  OpticalSegmentOptions merge;
  merge.range_len = 24;
  OpticalSegmentOptions no_merge = merge;
  no_merge.merge = false;
  const Score with = Evaluate(sc, SegmentOptical(sc.photo, merge));
  const Score without = Evaluate(sc, SegmentOptical(sc.photo, no_merge));
  std::printf("[ortho] pitched roofs whole: %d with merging, %d without\n", with.pitched_merged,
              without.pitched_merged);
  EXPECT_GT(with.pitched_merged, without.pitched_merged + 2);
}

TEST(OpticalRegions, ConsumingOverloadGivesTheSameRegionsAndFreesThePhoto) {
  const Scene sc = MakeScene(2, 500);
  cv::Mat1i labels_kept, labels_moved;
  const std::vector<PhotoRegion> kept = SegmentOptical(sc.photo, {}, &labels_kept);
  cv::Mat moved = sc.photo.clone();
  const std::vector<PhotoRegion> consumed = SegmentOptical(std::move(moved), {}, &labels_moved);
  EXPECT_TRUE(moved.empty());  // the caller's pixels were released
  ASSERT_EQ(kept.size(), consumed.size());
  ASSERT_GT(kept.size(), 3u);
  for (size_t i = 0; i < kept.size(); ++i) EXPECT_EQ(kept[i].contour, consumed[i].contour) << i;
  EXPECT_EQ(cv::norm(labels_kept, labels_moved, cv::NORM_INF), 0.0);
}

TEST(OpticalRegions, StoredFbmModelFittedOnNonBuildingAreas) {
  // "Fitted once per dataset": fit on one labelled scene's non-building
  // pixels (ground truth), save, load, use on another scene.
  const Scene train = MakeScene(4);
  cv::Mat1b non_building(train.photo.size(), 255);
  for (auto& m : train.roof_masks) non_building.setTo(0, m);
  const FbmModel fitted = FitFbm({train.photo}, {non_building});
  const std::string path = (std::filesystem::temp_directory_path() / "mvkp_ortho_fbm_city.json").string();
  SaveFbmModel(path, fitted);
  OpticalSegmentOptions o;
  o.fbm = LoadFbmModel(path);
  const Scene test = MakeScene(5);
  const Score s = Evaluate(test, SegmentOptical(test.photo, o));
  std::printf("[ortho] stored fBm (k %.2f H %.3f): %d/%zu roofs, %d/%d false\n", o.fbm.k, o.fbm.H, s.found,
              test.roof_masks.size(), s.false_regions, s.regions);
  EXPECT_GE(s.found, 0.7 * test.roof_masks.size());
  EXPECT_LE(s.false_regions, 0.25 * s.regions);
}

TEST(OpticalRegions, UniformImageHasNoRegions) {
  cv::Mat3b img(400, 400, cv::Vec3b(128, 128, 128));
  EXPECT_TRUE(SegmentOptical(img).empty());
  cv::Mat3b dark(300, 300, cv::Vec3b(20, 20, 20));
  EXPECT_TRUE(SegmentOptical(dark).empty());
}

TEST(OpticalRegions, SingleRoofOnGrass) {
  cv::RNG rng(5);
  cv::Mat3b img(200, 200);
  cv::Mat1f t = Noise(img.size(), 12, 4, rng) + Noise(img.size(), 8, 1, rng);
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) img(y, x) = cv::Vec3b(cv::saturate_cast<uint8_t>(50 + t(y, x)),
                                                   cv::saturate_cast<uint8_t>(115 + t(y, x)),
                                                   cv::saturate_cast<uint8_t>(70 + t(y, x)));
  cv::rectangle(img, cv::Rect(60, 50, 80, 60), cv::Scalar(170, 170, 170), cv::FILLED);
  const auto regions = SegmentOptical(img);
  ASSERT_EQ(regions.size(), 1u);
  cv::Mat1b gt(img.size(), 0);
  cv::rectangle(gt, cv::Rect(60, 50, 80, 60), 255, cv::FILLED);
  EXPECT_GT(Iou(RegionMask(regions[0], img.size()), gt), 0.9);
  EXPECT_EQ(regions[0].bbox, cv::boundingRect(regions[0].contour));
  EXPECT_LT(Shoelace(regions[0].contour), 0);
  EXPECT_LT(cv::contourArea(regions[0].contour, true), 0);  // the header's statement of the convention
  EXPECT_NEAR(regions[0].area, 80 * 60, 0.1 * 80 * 60);
}

TEST(OpticalRegions, TinyGreyAndBgraImages) {
  EXPECT_TRUE(SegmentOptical(cv::Mat3b(3, 3, cv::Vec3b(10, 200, 30))).empty());
  EXPECT_TRUE(SegmentOptical(cv::Mat1b(1, 1, 7)).empty());
  cv::Mat1b grey(120, 120, 60);
  cv::rectangle(grey, cv::Rect(30, 30, 50, 40), 190, cv::FILLED);
  const auto from_grey = SegmentOptical(grey);
  cv::Mat bgra;
  cv::cvtColor(grey, bgra, cv::COLOR_GRAY2BGRA);
  const auto from_bgra = SegmentOptical(bgra);
  ASSERT_EQ(from_grey.size(), from_bgra.size());
  EXPECT_GE(from_grey.size(), 1u);
}

TEST(OpticalRegions, RejectsBadInput) {
  EXPECT_THROW(SegmentOptical(cv::Mat()), Error);
  EXPECT_THROW(SegmentOptical(cv::Mat1f(10, 10, 0.f)), Error);
  OpticalSegmentOptions o;
  o.seed_cell = 0;
  EXPECT_THROW(SegmentOptical(cv::Mat3b(10, 10), o), Error);
}

TEST(OpticalRegions, Montpellier) {
  const std::string path = DataDir() + "/aerial/montpellier/ortho_rgb_20cm.tif";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no " << path;
  const cv::Mat img = cv::imread(path, cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty()) << path;
  Timer timer;
  const auto regions = SegmentOptical(img);
  const double ms = timer.ElapsedMs();
  cv::Mat big;
  cv::resize(DrawPhotoRegions(img, regions), big, cv::Size(), 3, 3, cv::INTER_NEAREST);
  cv::imwrite("/tmp/mvkp_ortho_montpellier.png", big);
  cv::resize(DrawOpticalMaps(img), big, cv::Size(), 3, 3, cv::INTER_NEAREST);
  cv::imwrite("/tmp/mvkp_ortho_montpellier_maps.png", big);
  std::printf("[ortho] montpellier %dx%d: %zu regions in %.1f ms\n", img.cols, img.rows, regions.size(), ms);
  for (auto& r : regions)
    std::printf("  area %6.0f bbox %3d,%3d %3dx%3d conf %.2f lda %.2f pref %d\n", r.area, r.bbox.x, r.bbox.y,
                r.bbox.width, r.bbox.height, r.confidence, r.lda_score, r.color_preference);
  EXPECT_GE(regions.size(), 2u);
  EXPECT_LE(regions.size(), 30u);
}

// ---------------------------------------------------------------- models

TEST(OrthoModels, FbmFitOnSyntheticTexture) {
  cv::RNG rng(3);
  const cv::Size sz(300, 300);
  // Fixed order (the operands of one sum are evaluated in any order).
  const cv::Mat1f n3 = Noise(sz, 6, 1, rng), n2 = Noise(sz, 10, 4, rng), n1 = Noise(sz, 16, 16, rng);
  cv::Mat1f t = n1 + n2 + n3;
  cv::Mat1b g;
  t += 128;
  t.convertTo(g, CV_8U);
  const FbmModel m = FitFbm({g}, {cv::Mat1b(sz, 255)});
  std::printf("[ortho] fBm fit: k %.2f H %.3f ofe %.2f\n", m.k, m.H, m.ofe);
  ASSERT_TRUE(m.Valid());
  EXPECT_GT(m.H, 0.05);
  EXPECT_LT(m.H, 0.95);
  // Smooth (man-made) patches have a higher fractal error than the texture.
  cv::Mat1b flat(sz, 128);
  EXPECT_GT(cv::mean(OverallFractalError(flat, m)(cv::Rect(10, 10, 280, 280)))[0], m.ofe);
  // computed in row strips (the memory-saving default) = all at once
  const cv::Mat1f whole = OverallFractalError(g, m, 0);
  for (int strip : {1, 7, 96}) {
    const cv::Mat1f strips = OverallFractalError(g, m, strip);
    ASSERT_EQ(strips.size(), whole.size());
    double worst = 0;
    for (int y = 0; y < whole.rows; ++y)
      for (int x = 0; x < whole.cols; ++x) worst = std::max(worst, double(std::abs(strips(y, x) - whole(y, x))));
    EXPECT_LT(worst, 1e-3) << "strip_rows " << strip;
  }

  const std::string path = (std::filesystem::temp_directory_path() / "mvkp_ortho_fbm.json").string();
  SaveFbmModel(path, m);
  const FbmModel l = LoadFbmModel(path);
  EXPECT_NEAR(l.k, m.k, 1e-9);
  EXPECT_NEAR(l.H, m.H, 1e-9);
  EXPECT_NEAR(l.ofe, m.ofe, 1e-9);
  EXPECT_EQ(l.window, m.window);
  EXPECT_THROW(LoadFbmModel(path + ".missing"), Error);
  EXPECT_THROW(LoadRegionLda(path), Error);  // wrong type
  EXPECT_THROW(FitFbm({g}, {cv::Mat1b(sz, 0)}), Error);
}

TEST(OrthoModels, RegionLdaSeparatesBuildingsFromBlobs) {
  const RegionLda lda = DefaultRegionLda();
  ASSERT_TRUE(lda.Valid());
  std::vector<cv::Vec2d> p;
  std::vector<int> l;
  DefaultRegionLdaTrainingSet(&p, &l, 99);  // held-out draw
  int correct = 0;
  for (size_t i = 0; i < p.size(); ++i) correct += (lda.Score(p[i]) > 0) == (l[i] == 1);
  const double acc = double(correct) / p.size();
  std::printf("[ortho] region LDA held-out accuracy %.1f %% (w %.2f %.2f %.2f %.2f %.2f b %.2f)\n", 100 * acc,
              lda.w[0], lda.w[1], lda.w[2], lda.w[3], lda.w[4], lda.b);
  EXPECT_GT(acc, 0.65);
  // An axis-aligned rectangle is regular.
  std::vector<cv::Point> rect;
  for (int x = 0; x < 60; ++x) rect.emplace_back(x, 0);
  for (int y = 0; y < 40; ++y) rect.emplace_back(60, y);
  for (int x = 60; x > 0; --x) rect.emplace_back(x, 40);
  for (int y = 40; y > 0; --y) rect.emplace_back(0, y);
  EXPECT_GT(lda.Score(ContourPnr(rect)), 0);

  const std::string path = (std::filesystem::temp_directory_path() / "mvkp_ortho_lda.json").string();
  SaveRegionLda(path, lda);
  const RegionLda back = LoadRegionLda(path);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(back.w[i], lda.w[i], 1e-9 * (1 + std::abs(lda.w[i])));
  EXPECT_NEAR(back.b, lda.b, 1e-9 * (1 + std::abs(lda.b)));
  EXPECT_THROW(TrainRegionLda({{0.5, 0.5}}, {1}), Error);
}

}  // namespace
}  // namespace mvkp
