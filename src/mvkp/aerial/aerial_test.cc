#include "mvkp/aerial/aerial.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/city/synth_city.h"
#include "mvkp/core/error.h"

namespace mvkp {
namespace {

// Mean error of the ground-truth building corners seen in the photo.
double CornerError(const City& c, const cv::Matx33d& H) {
  const cv::Matx33d Hi = c.photo_to_depth.inv();
  double sum = 0;
  int n = 0;
  for (const auto& fp : c.footprints)
    for (const auto& q : fp) {
      const cv::Point2f p = TransformPoints(Hi, {q})[0];
      if (p.x < 0 || p.y < 0 || p.x > c.photo.cols - 1 || p.y > c.photo.rows - 1) continue;
      sum += cv::norm(TransformPoints(H, {p})[0] - q);
      ++n;
    }
  return n ? sum / n : 1e9;
}

// An answer, if any, within 5 depth px of the truth ("not found" beats a
// wrong outline).
void ExpectRightOrNone(const City& c, const AerialRegistration& r) {
  if (r.registration.ok) {
    EXPECT_LE(CornerError(c, r.registration.photo_to_depth), 5.0) << r.registration.reason;
  }
}

// The outline search as it was before completeness and the trees
// (2026-12-07): the scenes earlier tests were found on.
AerialOptions OutlineSearchBeforeCompleteness() {
  AerialOptions o;
  o.outline_objects = false;
  o.outline.completeness_power = 0;
  return o;
}

TEST(Aerial, RegistersGeneratedScenesOrSaysNo) {
  CityOptions o;
  o.width = o.height = 600;
  o.buildings = 24;
  int good = 0;
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    const City c = MakeCity(o, seed);
    const AerialRegistration r = RegisterAerial(c.depth, c.photo);
    EXPECT_FALSE(r.depth_regions.empty());
    EXPECT_FALSE(r.photo_regions.empty());
    EXPECT_EQ(r.photo_regions.size(), r.photo_region_confidence.size());
    if (!r.registration.ok) {
      EXPECT_EQ(r.registration.reason.rfind("no registration found", 0), 0u) << r.registration.reason;
      continue;
    }
    const double e = CornerError(c, r.registration.photo_to_depth);
    EXPECT_LE(e, 5.0) << "seed " << seed << ": a wrong registration reported as success (" << r.registration.reason
                      << ")";
    good += e <= 5.0;
  }
  EXPECT_GE(good, 2);
}

// Issue 21: small tiles with 4 buildings, which the region method rarely
// registers. Over 12 scenes of `mvkp synth-city --buildings 4 --width 200
// --height 200 --seed 1` (seed 1000003 + i), the outline search (kOutlines)
// registers some within 5 px, with a confidence at or above its threshold,
// and no answer of it or of kAuto is wrong; kAuto says which method answered.
// (Counted, not per scene: another compiler's rounding changes the scenes.)
TEST(Aerial, OutlineSearchRegistersSmallTiles) {
  CityOptions o;
  o.width = o.height = 200;
  o.buildings = 4;
  int registered = 0;
  for (std::uint64_t seed = 1000003; seed < 1000015; ++seed) {
    const City c = MakeCity(o, seed);
    AerialOptions ao;
    ao.method = AerialOptions::Method::kOutlines;
    const AerialRegistration r = RegisterAerial(c.depth, c.photo, ao);
    EXPECT_TRUE(r.photo_regions.empty());  // no photo segmentation in this mode
    if (r.registration.ok) {
      ++registered;
      EXPECT_EQ(r.method, "outlines");
      EXPECT_GE(r.confidence, OutlineSearchOptions{}.min_confidence);
      EXPECT_LE(CornerError(c, r.registration.photo_to_depth), 5.0) << "seed " << seed;
    }
    AerialOptions only_regions;
    only_regions.method = AerialOptions::Method::kRegions;
    const AerialRegistration g = RegisterAerial(c.depth, c.photo, only_regions);
    EXPECT_FALSE(g.outline_search_ran);
    EXPECT_TRUE(!g.registration.ok || g.method == "regions");
    const AerialRegistration a = RegisterAerial(c.depth, c.photo);
    if (a.registration.ok) {
      EXPECT_TRUE(a.method == "regions" || a.method == "single-pair" || a.method == "outlines" ||
                  a.method == "cast-shadows");
      EXPECT_LE(CornerError(c, a.registration.photo_to_depth), 5.0) << "seed " << seed << " (auto, " << a.method << ")";
    }
  }
  EXPECT_GE(registered, 1) << "of 12 small tiles";
  std::printf("outline search registered %d of 12 small tiles\n", registered);
}

// Photos of other ground (no overlap) are refused by the outline search too.
TEST(Aerial, OutlineSearchRefusesOtherGround) {
  CityOptions o;
  o.width = o.height = 200;
  o.buildings = 4;
  o.overlap = false;
  for (std::uint64_t seed : {1001000u, 1001001u, 1001002u, 1001003u, 1001004u, 1001005u}) {
    const City c = MakeCity(o, seed);
    AerialOptions ao;
    ao.method = AerialOptions::Method::kOutlines;
    const AerialRegistration r = RegisterAerial(c.depth, c.photo, ao);
    EXPECT_FALSE(r.registration.ok) << "seed " << seed << ": other ground registered (" << r.registration.reason << ")";
    EXPECT_EQ(r.registration.reason.rfind("no registration found", 0), 0u) << r.registration.reason;
  }
}

// Registers a photo of other ground with the default options and expects
// "no registration found".
AerialRegistration ExpectRefused(const City& c, const AerialOptions& options = {}) {
  AerialRegistration r = RegisterAerial(c.depth, c.photo, options);
  EXPECT_FALSE(r.registration.ok) << "other ground registered (" << r.registration.reason << ")";
  EXPECT_EQ(r.registration.reason.rfind("no registration found", 0), 0u) << r.registration.reason;
  return r;
}

// Issue 21 (fresh seed 107, small tiles): a photo of other ground where the
// outline search found a pose that puts 3 outlines on edges by tilting and
// stretching the photo (divisor change 0.40, anisotropy 1.58). Every route
// now applies the nadir-shape checks, so it is refused. (The scene of
// `mvkp synth-city --style dense --width 200 --height 200 --buildings 5
// --trees 4 --no-overlap --seed 1107003322`; another compiler's rounding
// draws another scene, which must be refused as well.)
TEST(Aerial, OutlineSearchPosesHaveANadirShape) {
  CityOptions o;
  o.width = o.height = 200;
  o.buildings = 5;
  o.trees = 4;
  o.style = "dense";
  o.overlap = false;
  ExpectRefused(MakeCity(o, 1107003322u));
  // the public check itself: a similarity passes; a stretch or a steep tilt does not
  const cv::Rect2d extent(0, 0, 800, 600);
  const RegistrationOptions ro;
  EXPECT_EQ(NadirShape(cv::Matx33d(0.5, -0.2, 10, 0.2, 0.5, 20, 0, 0, 1), extent, ro), "");
  EXPECT_NE(NadirShape(cv::Matx33d(0.7, 0, 0, 0, 0.5, 0, 0, 0, 1), extent, ro).find("stretches"), std::string::npos);
  EXPECT_NE(NadirShape(cv::Matx33d(1, 0, 0, 0, 1, 0, 1e-3, 1e-3, 1), extent, ro).find("perspective"), std::string::npos);
  RegistrationOptions off;
  off.max_anisotropy = off.max_perspective = 0;
  EXPECT_EQ(NadirShape(cv::Matx33d(0.7, 0, 0, 0, 0.5, 0, 0, 0, 1), extent, off), "");
}

// Issue 21 (seed 117, suburb): a photo of other ground that the outline
// search registered with 6 of 8 outlines on edges (contrast 2.14) and roofs
// of 0.99 over 7 outlines. The roof veto of the region routes now judges
// the outline search's answers too. (`mvkp synth-city --style suburb
// --no-overlap --seed 1117`, scene 9; another compiler's rounding draws
// another scene, which must be refused as well.)
TEST(Aerial, OutlineSearchAnswersPassTheRoofVeto) {
  CityOptions o;
  o.style = "suburb";
  o.overlap = false;
  const City c = MakeCity(o, 1117003360u);
  const AerialRegistration r = ExpectRefused(c);
  if (r.outline_search_ran && r.outline.roof_vetoed) {
    // refused for its roofs: scored over enough outlines, below the veto
    EXPECT_GE(r.outline.edge.roof_regions, EdgeEvidenceOptions{}.min_roof_regions);
    EXPECT_LT(r.outline.edge.roof_contrast, EdgeEvidenceOptions{}.roof_veto);
    EXPECT_NE(r.registration.reason.find("roofs apart from the ground"), std::string::npos) << r.registration.reason;
  }
}

// Issue 21 (seed 124, classic photos of other ground, scene 7): on the
// photo with its cast shadows relit (the fallback pass), the single-pair
// route registered a photo of other ground with 4 of 8
// outlines on edges (contrast 3.18, margin 0.54) and roofs of 0.54 over 6
// outlines, let through because its edges were above roof_veto_below. One
// region pair now needs its roofs set apart whatever the edges. (`mvkp
// synth-city --no-overlap --seed 1124`, scene 7.) With the default margin
// (0.5) this scene's pair stops at 0.49, before the roofs are looked at;
// the margin is lowered to 0.45 here so that the roof rule is what refuses
// it. Another compiler's rounding may draw another scene, which must be
// refused as well, for whatever reason.
TEST(Aerial, SinglePairAnswersNeedRoofsApart) {
  CityOptions o;
  o.overlap = false;
  const City c = MakeCity(o, 1124003379u);
  AerialOptions ao;
  ao.registration.single_pair_min_confidence = 0.45;
  const AerialRegistration r = ExpectRefused(c, ao);
  const size_t at = r.registration.reason.find("one region pair needs roofs set apart");
  if (at != std::string::npos) {
    double roofs = 9;
    ASSERT_EQ(std::sscanf(r.registration.reason.c_str() + at, "one region pair needs roofs set apart from the "
                                                                "ground (roof contrast %lf", &roofs), 1);
    EXPECT_LT(roofs, EdgeEvidenceOptions{}.roof_veto);
  }
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
  // the scene this was found on (GCC, x86-64): the roof rule is what refuses it
  EXPECT_NE(at, std::string::npos) << r.registration.reason;
#endif
}

// Options under which the region routes find nothing (1000 region pairs
// needed, no single-pair route): kAuto then falls back to the outline
// search on whatever scene a compiler's rounding draws.
AerialOptions RegionsFindNothing() {
  AerialOptions o;
  o.registration.min_regions = o.registration.min_regions_with_evidence = 1000;
  o.registration.single_pair_route = false;
  return o;
}

// Issue 21 (seed 108, dense style, 1000 x 1000 tiles of ~30 buildings): on
// coarse photos the segmentation merges the roofs and the regions find no
// consistent set; kAuto now runs the outline search on large tiles too (on a
// 600 px copy of the photo), where it used to stop at 12 building regions.
// Seed 108's dense scenes 3, 7 and 34 (`mvkp synth-city --style dense --seed
// 108`; the regions miss them, the outline search registers them within
// 1.2 px with GCC). Counted, not per scene: another compiler draws other
// scenes, so the region routes are made to find nothing here.
TEST(Aerial, OutlineSearchRegistersLargeTilesTheRegionsMiss) {
  CityOptions o;
  o.style = "dense";
  const AerialOptions ao = RegionsFindNothing();
  int registered = 0;
  for (std::uint64_t seed : {108000327u, 108000331u, 108000358u}) {
    const City c = MakeCity(o, seed);
    const AerialRegistration r = RegisterAerial(c.depth, c.photo, ao);
    EXPECT_GT(r.depth_regions.size(), 12u) << "seed " << seed;
    EXPECT_TRUE(r.outline_search_ran) << "seed " << seed;
    if (!r.registration.ok) continue;
    EXPECT_EQ(r.method, "outlines");
    EXPECT_LE(CornerError(c, r.registration.photo_to_depth), 5.0) << "seed " << seed << ": " << r.registration.reason;
    EXPECT_GE(r.confidence, AerialOptions{}.outline.min_confidence);
    EXPECT_LE(r.registration.ambiguity_px, RegistrationOptions{}.ambiguity_px);
    ++registered;
    if (registered == 1) {  // the old limit: no outline search on a tile this size, no answer
      AerialOptions limited = ao;
      limited.auto_outline_max_regions = 12;
      const AerialRegistration r12 = RegisterAerial(c.depth, c.photo, limited);
      EXPECT_FALSE(r12.outline_search_ran);
      EXPECT_FALSE(r12.registration.ok);
    }
  }
  EXPECT_GE(registered, 1) << "of 3 large tiles";
}

// Issue 21 (seed 126, dense scene 20: `mvkp synth-city --style dense --seed
// 126`): the outline search finds the right basin with a clear margin
// (confidence 0.92) but its pose, refined, stays ~6 px off, with 18 of 36
// outlines on edges, short of the 0.6 a large tile asks. Relocated
// (AerialOptions::outline_relocate_confidence), 29 of 35 lie on edges and
// the answer is within 0.3 px (GCC, x86-64). Whatever scene another
// compiler's rounding draws, a relocated answer must be right.
TEST(Aerial, AClearOutlineWinnerIsRelocatedOntoTheEdges) {
  CityOptions o;
  o.style = "dense";
  const City c = MakeCity(o, 126000398u);
  const AerialOptions ao = RegionsFindNothing();
  const AerialRegistration r = RegisterAerial(c.depth, c.photo, ao);
  ASSERT_TRUE(r.outline_search_ran);
  const bool relocated = r.registration.reason.find("px onto edges") != std::string::npos;
  ExpectRightOrNone(c, r);
  AerialOptions off = ao;
  off.outline_relocate_confidence = 0;
  // without the relocation the cast shadows single out a pose here (margin
  // >= 0.3), which must be right when it answers
  const AerialRegistration v = RegisterAerial(c.depth, c.photo, off);
  ExpectRightOrNone(c, v);
  off.cast_shadow_confirm_margin = 0;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
  EXPECT_EQ(w.registration.reason.find("px onto edges"), std::string::npos);
  if (relocated) {
    EXPECT_TRUE(r.registration.ok);
    EXPECT_GE(r.outline.confidence, ao.outline_relocate_confidence);
  }
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
  // the scene this was found on: refused without the relocation, right with it
  EXPECT_TRUE(relocated) << r.registration.reason;
  EXPECT_FALSE(w.registration.ok) << w.registration.reason;
#endif
  AerialOptions bad;
  bad.outline_relocate_confidence = 1.5;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// Photo contours come back in full-size photo px: a photo upscaled 2x
// (nearest) and segmented at the original size gives the original regions, at
// twice the coordinates (pixel centres at integers: x' = 2x + 0.5).
TEST(Aerial, PhotoContoursInFullSizePixels) {
  CityOptions o;
  o.width = o.height = 500;
  o.buildings = 16;
  const City c = MakeCity(o, 21);
  AerialOptions keep;
  keep.photo_max_side = 0;
  keep.photo_min_side = 0;  // the regions of the working size, whatever the answer
  const AerialRegistration a = RegisterAerial(c.depth, c.photo, keep);
  cv::Mat big;
  cv::resize(c.photo, big, cv::Size(), 2, 2, cv::INTER_NEAREST);
  AerialOptions down;
  down.photo_max_side = std::max(c.photo.cols, c.photo.rows);
  down.photo_min_side = 0;
  const AerialRegistration b = RegisterAerial(c.depth, big, down);
  ASSERT_FALSE(a.photo_regions.empty());
  ASSERT_EQ(a.photo_regions.size(), b.photo_regions.size());
  for (size_t i = 0; i < a.photo_regions.size(); ++i) {
    ASSERT_EQ(a.photo_regions[i].size(), b.photo_regions[i].size());
    for (size_t j = 0; j < a.photo_regions[i].size(); ++j) {
      EXPECT_NEAR(b.photo_regions[i][j].x, 2 * a.photo_regions[i][j].x + 0.5, 1e-3);
      EXPECT_NEAR(b.photo_regions[i][j].y, 2 * a.photo_regions[i][j].y + 0.5, 1e-3);
    }
  }
}

// Issue 21: coarse photos (2-3 depth px per photo px, houses 5-8 photo px
// across; `mvkp synth-city --style suburb --width 600 --height 600
// --buildings 40 --min-scale 2 --max-scale 3 --seed 77`). The segmentation
// at the photo's own size merges roofs with gardens and the regions find
// nothing; segmented upscaled (photo_min_side), some register. Every answer
// is within 5 px, an upscaled answer's regions come back in photo px, the
// working size alone does not answer it, and the stricter acceptance of the
// upscaled route refuses it when asked for more pairs than it has. Counted,
// not per scene: another compiler draws other scenes (GCC: scenes 2 and 5).
TEST(Aerial, CoarsePhotosAreSegmentedUpscaled) {
  CityOptions o;
  o.style = "suburb";
  o.width = o.height = 600;
  o.buildings = 40;
  o.min_scale = 2;
  o.max_scale = 3;
  int upscaled = 0;
  for (std::uint64_t i = 0; i < 10; ++i) {
    const std::uint64_t seed = 77u * 1000003u + i;
    const City c = MakeCity(o, seed);
    ASSERT_LT(std::max(c.photo.cols, c.photo.rows), AerialOptions{}.photo_min_side);
    const AerialRegistration r = RegisterAerial(c.depth, c.photo);
    if (!r.registration.ok) continue;
    EXPECT_LE(CornerError(c, r.registration.photo_to_depth), 5.0) << "seed " << seed << ": " << r.registration.reason;
    if (r.photo_upscale == 1) continue;
    ++upscaled;
    EXPECT_EQ(r.method, "regions");
    EXPECT_GE(r.registration.region_matches.size(), size_t(AerialOptions{}.upscaled_min_pairs));
    EXPECT_GE(r.registration.edge.contrast, AerialOptions{}.upscaled_min_edge_contrast);
    for (const Contour& pc : r.photo_regions)
      for (const auto& p : pc) {
        ASSERT_GE(p.x, -1.f);
        ASSERT_GE(p.y, -1.f);
        ASSERT_LE(p.x, float(c.photo.cols));
        ASSERT_LE(p.y, float(c.photo.rows));
      }
    if (upscaled == 1) {
      AerialOptions native;
      native.photo_min_side = 0;
      native.method = AerialOptions::Method::kRegions;
      EXPECT_FALSE(RegisterAerial(c.depth, c.photo, native).registration.ok) << "seed " << seed;
      AerialOptions strict;
      strict.upscaled_min_pairs = int(r.registration.region_matches.size()) + 1;
      strict.method = AerialOptions::Method::kRegions;
      const AerialRegistration s2 = RegisterAerial(c.depth, c.photo, strict);
      EXPECT_FALSE(s2.registration.ok) << "seed " << seed;
      EXPECT_NE(s2.registration.reason.find("an upscaled segmentation needs"), std::string::npos) << s2.registration.reason;
    }
  }
  EXPECT_GE(upscaled, 1) << "of 10 coarse photos";
}

// A town of small look-alike houses (suburb style, `synth-city --style
// suburb --seed 1` scene 0): region shapes alone pair 5 houses, sheds and
// pools with the photo squeezed onto a patch of the depth, hundreds of px
// off, with the outlines not on photo edges. The default acceptance needs
// the image check and refuses it; shapes alone (the old default) take it.
TEST(Aerial, LookAlikeHousesAreRefusedWithoutImageEvidence) {
  CityOptions o;
  o.style = "suburb";
  const City c = MakeCity(o, 1000003);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  if (r.registration.ok) {
    EXPECT_LT(CornerError(c, r.registration.photo_to_depth), 5.0) << r.registration.reason;
  }
  // (with the hedges as depth regions, as before their width was checked:
  // they made the look-alike sets on this scene)
  AerialOptions shapes;
  shapes.registration.require_image_evidence = false;
  shapes.depth.min_width_px = 0;
  shapes.depth.lcc_slope = 0;  // and without the pitched roofs (fewer houses, as then)
  shapes.registration.max_anisotropy = 0;  // and without the square-pixel check
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, shapes);
  ASSERT_TRUE(w.registration.ok) << w.registration.reason;
  EXPECT_GT(CornerError(c, w.registration.photo_to_depth), 50.0);
  EXPECT_LT(w.registration.edge.contrast, 1.8);
  // That squeeze stretches the photo 1.37x more along one axis than the
  // other: the square-pixel check alone refuses it too.
  shapes.registration.max_anisotropy = RegistrationOptions{}.max_anisotropy;
  const AerialRegistration s2 = RegisterAerial(c.depth, c.photo, shapes);
  if (s2.registration.ok) {
    EXPECT_LT(CornerError(c, s2.registration.photo_to_depth), 5.0) << s2.registration.reason;
  }
}

// A dense town whose first consistent set of region pairs is right by its
// regions and 12 px off away from them (held-back seed 103 of
// scripts/aerial_eval.py, dense scene 27, looked at since): refined from a
// perturbed perspective, another pose puts the outlines on the edges as
// well, 8+ px away, so that answer is refused (RegistrationOptions::
// ambiguity_px) and the search goes on. Whatever answers then is right.
TEST(Aerial, AnAnswerTheEvidenceDoesNotDetermineIsRefused) {
  CityOptions o;
  o.style = "dense";
  const City c = MakeCity(o, 103u * 1000003u + 27u);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  if (r.registration.ok) {
    EXPECT_LE(CornerError(c, r.registration.photo_to_depth), 5.0) << r.registration.reason;
    EXPECT_LE(r.registration.ambiguity_px, RegistrationOptions{}.ambiguity_px);
  }
  // Without the check (GCC's build: 12.3 px off; another compiler's rounding
  // changes the scene, so this part is printed, not asserted).
  AerialOptions off;
  off.registration.ambiguity_px = 0;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
  EXPECT_EQ(w.registration.ambiguity_px, 0);
  const std::string with = r.registration.ok ? cv::format("%.1f px", CornerError(c, r.registration.photo_to_depth))
                                             : r.registration.reason;
  if (w.registration.ok)
    std::printf("without the check: %.1f px off (%s); with it: %s\n", CornerError(c, w.registration.photo_to_depth),
                w.registration.reason.c_str(), with.c_str());
  else
    std::printf("without the check: %s; with it: %s\n", w.registration.reason.c_str(), with.c_str());
  AerialOptions bad;
  bad.registration.ambiguity_px = -1;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
  bad.registration.ambiguity_px = 5, bad.registration.ambiguity_perspective = 0;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// A dense town whose region pairs hold the answer 5.3 px off (held-back seed
// 123 of scripts/aerial_eval.py, dense scene 10, looked at since): the
// photo segmentation drew roofs with their cast shadows, and the relocation
// that puts the outlines on edges 19 % better (at 1.7 px from the truth)
// leaves those pairs at RMS 4.6 px, over the bound of 3.0. With
// RegistrationOptions::relocate_rms_free_gain the edges decide.
TEST(Aerial, ARelocationTheEdgesClearlyPreferIsKept) {
  CityOptions o;
  o.style = "dense";
  const City c = MakeCity(o, 123u * 1000003u + 10u);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  ExpectRightOrNone(c, r);
  // Without it (GCC's build: 5.3 px off; another compiler's rounding changes
  // the scene, so this part is printed, not asserted).
  AerialOptions off;
  off.registration.relocate_rms_free_gain = 0;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
  std::printf("with the gain: %s (relocated %.1f px); without: %s\n",
              r.registration.ok ? cv::format("%.1f px", CornerError(c, r.registration.photo_to_depth)).c_str()
                                : r.registration.reason.c_str(),
              r.registration.relocated_px,
              w.registration.ok ? cv::format("%.1f px", CornerError(c, w.registration.photo_to_depth)).c_str()
                                : w.registration.reason.c_str());
  AerialOptions bad;
  bad.registration.relocate_rms_free_gain = -1;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// A lean trap whose edges are nearly as good as the truth's, and whose
// roofs are not (seed 134 civic 21, a tuning seed: `mvkp synth-city --style
// civic --seed 134`, scene 21). The region pairs' answer, refined at lean
// 0, is 5.5 px off on the ground; the lean jump's best pose puts the
// outlines on edges 3 % better (below relocate_lean_gain, 5 %) and its roofs
// stand apart 37 % more (1.66 -> 2.27). With relocate_lean_roof_gain the
// roofs decide, and the answer is 2.1 px from the truth.
TEST(Aerial, ALeanJumpTheRoofsClearlyPreferIsKept) {
  CityOptions o;
  o.style = "civic";
  const City c = MakeCity(o, 134u * 1000003u + 21u);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  ASSERT_TRUE(r.registration.ok) << r.registration.reason;
  EXPECT_LE(CornerError(c, r.registration.photo_to_depth), 5.0) << r.registration.reason;
  AerialOptions off;
  off.edge.relocate_lean_roof_gain = 0;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
  std::printf("with the roofs: %.1f px (relocated %.1f px); edges alone: %s\n",
              CornerError(c, r.registration.photo_to_depth), r.registration.relocated_px,
              w.registration.ok ? cv::format("%.1f px", CornerError(c, w.registration.photo_to_depth)).c_str()
                                : w.registration.reason.c_str());
  AerialOptions bad;
  bad.edge.relocate_lean_min_gain = 0.1;  // above relocate_lean_gain
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
  bad.edge.relocate_lean_min_gain = 0.02, bad.edge.relocate_lean_roof_gain = -1;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// The lean answer must not lower the roofs (RegistrationOptions::
// lean_min_roof_ratio). Two classic scenes of tuning seeds, true orthophotos
// where the region route's lean answer put the outlines on edges as well as
// the lean-free one and its roofs stood apart 11 % less. Seed 132 scene 26:
// 0.2 px lean-free, 3.5 px with the lean; seed 135 scene 0: 4.9 px
// lean-free, 6.9 px (a wrong answer) with the lean.
TEST(Aerial, TheLeanAnswerMustNotLowerTheRoofs) {
  struct Case {
    unsigned seed;
    double max_px;
  };
  for (const Case k : {Case{132u * 1000003u + 26u, 1.0}, Case{135u * 1000003u + 0u, 5.0}}) {
    const City c = MakeCity(CityOptions{}, k.seed);
    const AerialRegistration r = RegisterAerial(c.depth, c.photo);
    ASSERT_TRUE(r.registration.ok) << k.seed << ": " << r.registration.reason;
    const double err = CornerError(c, r.registration.photo_to_depth);
    EXPECT_LE(err, k.max_px) << k.seed;
    AerialOptions off;
    off.registration.lean_min_roof_ratio = 0;
    const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
    std::printf("seed %u: with the roofs %.2f px (lean %.3f, %.3f); edges alone %s\n", k.seed, err,
                r.registration.lean_px_per_m.x, r.registration.lean_px_per_m.y,
                w.registration.ok ? cv::format("%.2f px", CornerError(c, w.registration.photo_to_depth)).c_str()
                                  : w.registration.reason.c_str());
  }
  AerialOptions bad;
  bad.registration.lean_min_roof_ratio = -0.5;
  const City c = MakeCity(CityOptions{}, 1u);
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// Cast shadows relit (ortho/shadows.h, opt-in) on a generated suburb,
// against the same scene rendered with the sun overhead (no cast shadows):
// the step is found in the photo, the relit pixels are mostly true shadow,
// and the relit photo is much closer to the one without shadows there.
// Seed 122 suburb 11, whose registration fails with its shadows as they are.
TEST(Aerial, CastShadowsAreRelit) {
  CityOptions o;
  o.style = "suburb";
  const City c = MakeCity(o, 122u * 1000003u + 11u);
  CityOptions overhead = o;
  overhead.sun_elevation_deg = 90, overhead.sun_azimuth_deg = 0;
  const City n = MakeCity(overhead, 122u * 1000003u + 11u);
  ASSERT_EQ(c.photo.size(), n.photo.size());
  cv::Mat3f a, b;
  c.photo.convertTo(a, CV_32F);
  n.photo.convertTo(b, CV_32F);
  cv::Mat1b truth(c.photo.size(), uint8_t(0));  // the cast shadows
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      const cv::Vec3f p = a(y, x), q = b(y, x);
      truth(y, x) = (q[0] + q[1] + q[2] + 3) > 1.25f * (p[0] + p[1] + p[2] + 3) ? 255 : 0;
    }
  ShadowCompensation info;
  cv::Mat1b mask;
  ShadowOptions so;
  so.enabled = true;
  const cv::Mat relit = CompensateShadows(c.photo, so, &info, &mask);
  ASSERT_TRUE(info.applied) << info.samples << " samples, " << info.votes << " votes";
  // blue drops least
  EXPECT_LT(info.log_step[2], info.log_step[1]);
  EXPECT_LT(info.log_step[1], info.log_step[0]);
  const double hit = cv::countNonZero(mask & truth), relit_px = cv::countNonZero(mask), shadow_px = cv::countNonZero(truth);
  EXPECT_GT(hit / relit_px, 0.6);   // precision
  std::printf("relit %.1f %% of the photo: precision %.2f, recall %.2f\n", 100.0 * relit_px / double(c.photo.total()), hit / relit_px, hit / shadow_px);
  EXPECT_GT(hit / shadow_px, 0.4);  // recall (0.49 at this full size)
  cv::Mat3f r;
  relit.convertTo(r, CV_32F);
  const cv::Scalar before = cv::mean(cv::abs(a - b), truth), after = cv::mean(cv::abs(r - b), truth);
  for (int ch = 0; ch < 3; ++ch) EXPECT_LT(after[ch], 0.6 * before[ch]) << "channel " << ch;
  // The registrations: the photo as it is (no fallback), relit first
  // (opt-in), and the default (the photo as it is, then the fallback on the
  // relit photo). Any answer must be right; which ones answer is printed.
  AerialOptions plain;
  plain.shadow_fallback = false;
  const AerialRegistration wo = RegisterAerial(c.depth, c.photo, plain);
  EXPECT_FALSE(wo.shadows.applied);
  AerialOptions on;
  on.shadows.enabled = true;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, on);
  EXPECT_TRUE(w.shadows.applied);
  EXPECT_FALSE(w.shadow_fallback_used);
  const AerialRegistration d = RegisterAerial(c.depth, c.photo);
  for (const AerialRegistration* r : {&wo, &w, &d}) {
    if (r->registration.ok) {
      EXPECT_LE(CornerError(c, r->registration.photo_to_depth), 5.0) << r->registration.reason;
    }
  }
  if (!wo.registration.ok && d.registration.ok) {
    EXPECT_TRUE(d.shadow_fallback_used);
    EXPECT_TRUE(d.shadows.applied);
    EXPECT_NE(d.method, "outlines");  // the fallback answers by region shapes only
  }
  if (wo.registration.ok) {
    EXPECT_FALSE(d.shadow_fallback_used);
  }
  auto said = [&](const AerialRegistration& r) {
    return r.registration.ok ? cv::format("%.1f px", CornerError(c, r.registration.photo_to_depth))
                             : r.registration.reason;
  };
  std::printf("as it is: %s\nrelit first: %s\ndefault (fallback %s): %s\n", said(wo).c_str(), said(w).c_str(),
              d.shadow_fallback_used ? "answered" : "did not answer", said(d).c_str());
  AerialOptions bad;
  bad.shadows.grow_window = 2;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// The shadows the depth casts (AerialOptions::cast_shadow_fallback): a
// shadowed suburb (seed 122 suburb 34, where the fallback was built) that
// neither the photo as it is nor its own shadow compensation registers. At
// the region set the checks refused, the depth's shadows stand out; relit
// there, the region route registers the photo. Any answer must be right.
TEST(Aerial, TheDepthsShadowsRelitRegisterAShadowedSuburb) {
  CityOptions o;
  o.style = "suburb";
  const City c = MakeCity(o, 122u * 1000003u + 34u);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  AerialOptions off;
  off.cast_shadow_fallback = false;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
  for (const AerialRegistration* a : {&r, &w})
    if (a->registration.ok) {
      EXPECT_LE(CornerError(c, a->registration.photo_to_depth), 5.0) << a->registration.reason;
    }
  EXPECT_FALSE(w.cast_shadow_fallback_used);
  EXPECT_FALSE(w.cast_shadows.found);
  if (r.cast_shadow_fallback_used) {
    EXPECT_TRUE(r.registration.ok);
    EXPECT_TRUE(r.cast_shadows.applied);
    EXPECT_NE(r.method, "outlines");  // the fallback answers by region shapes only
    const double gap = std::fmod(std::abs(r.cast_shadows.azimuth_deg - (c.sun_azimuth_deg + 180)), 360.0);
    EXPECT_LE(std::min(gap, 360 - gap), 15.0) << "the shadows point away from the sun";
  }
  std::printf("with the depth's shadows: %s\nwithout: %s\n",
              r.registration.ok ? cv::format("%.1f px", CornerError(c, r.registration.photo_to_depth)).c_str()
                                : r.registration.reason.c_str(),
              w.registration.ok ? "registered" : "no registration");
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
  // the scene this was built on: refused without the fallback, right with it
  EXPECT_TRUE(r.cast_shadow_fallback_used) << r.registration.reason;
  EXPECT_FALSE(w.registration.ok) << w.registration.reason;
#endif
  AerialOptions bad;
  bad.cast_shadows.azimuths = 4;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
  bad = AerialOptions{};
  bad.cast_shadow_candidates = -1;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// The pose the cast shadows single out, confirmed by its outlines and
// roofs on the relit photo (AerialOptions::cast_shadow_confirm_margin).
// Seed 122 suburb 14: no pass answers on its own; the sun stands out at a
// refused candidate. Seed 128 dense 4, at margin 0.25 (its sun stands out
// by 0.29, below the default 0.3): the candidate is 8.8 px off, its
// relocation lands 14.5 px off with roofs of 0.74; the roofs refuse it.
TEST(Aerial, APoseTheCastShadowsSingleOutIsConfirmedByItsRoofs) {
  CityOptions o;
  o.style = "suburb";
  const City c = MakeCity(o, 122u * 1000003u + 14u);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  AerialOptions off;
  off.cast_shadow_confirm_margin = 0;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
  for (const AerialRegistration* a : {&r, &w})
    if (a->registration.ok) {
      EXPECT_LE(CornerError(c, a->registration.photo_to_depth), 5.0) << a->registration.reason;
    }
  EXPECT_NE(w.method, "cast-shadows");
  if (r.method == "cast-shadows") {
    EXPECT_TRUE(r.registration.ok);
    EXPECT_GE(r.cast_shadows.margin, AerialOptions{}.cast_shadow_confirm_margin);
    EXPECT_GE(r.registration.edge.roof_contrast, EdgeEvidenceOptions{}.roof_accept);
    EXPECT_GT(r.confidence, 0);
  }
  std::printf("confirmed: %s\nwithout: %s\n",
              r.registration.ok ? cv::format("%s, %.1f px", r.method.c_str(),
                                             CornerError(c, r.registration.photo_to_depth)).c_str()
                                : r.registration.reason.c_str(),
              w.registration.ok ? "registered" : "no registration");
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
  // the scene this was built on: refused without the confirmation, right with it
  EXPECT_EQ(r.method, "cast-shadows") << r.registration.reason;
  EXPECT_FALSE(w.registration.ok) << w.registration.reason;
#endif

  o.style = "dense";
  const City d = MakeCity(o, 128u * 1000003u + 4u);
  AerialOptions low;
  low.cast_shadow_confirm_margin = 0.25;
  const AerialRegistration rd = RegisterAerial(d.depth, d.photo, low);
  if (rd.registration.ok) {
    EXPECT_LE(CornerError(d, rd.registration.photo_to_depth), 5.0) << rd.registration.reason;
  }

  AerialOptions bad;
  bad.cast_shadow_confirm_margin = -0.1;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
  bad = AerialOptions{};
  bad.cast_shadow_confirm_px = 0;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// The outline search's answer rests on edges alone: its roofs must stand
// apart whatever the edges (AerialOptions::outline_roof_veto_regions). Seed
// 129 suburb 19: the search's best pose is 772 px off, its 6 outlines in
// view all on edges (contrast 2.52), its roofs 0.74 over 4 outlines.
TEST(Aerial, AnOutlineAnswerWhoseRoofsDoNotStandApartIsRefused) {
  CityOptions o;
  o.style = "suburb";
  const City c = MakeCity(o, 129u * 1000003u + 19u);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  ExpectRightOrNone(c, r);
  if (r.method == "outlines") {
    EXPECT_GE(r.registration.edge.roof_contrast, EdgeEvidenceOptions{}.roof_veto);
  }
  // The search as it was when the rule was made (no objects, no
  // completeness, no completeness floor: since then the search no longer
  // finds that pose first).
  AerialOptions old = OutlineSearchBeforeCompleteness();
  old.outline.min_completeness = 0;
  const AerialRegistration ro = RegisterAerial(c.depth, c.photo, old);
  AerialOptions off = old;
  off.outline_roof_veto_regions = 0;
  const AerialRegistration w = RegisterAerial(c.depth, c.photo, off);
  // The completeness floor (OutlineSearchOptions::min_completeness) refuses
  // that pose too, without the roofs: 0.69 of its outlines' arcs on edges.
  AerialOptions floor_only = off;
  floor_only.outline.min_completeness = OutlineSearchOptions{}.min_completeness;
  const AerialRegistration f = RegisterAerial(c.depth, c.photo, floor_only);
  ExpectRightOrNone(c, f);
  std::printf("with the rule: %s\nwithout: %s\n", ro.registration.ok ? "registered" : ro.registration.reason.c_str(),
              w.registration.ok ? cv::format("%s, %.1f px", w.method.c_str(),
                                             CornerError(c, w.registration.photo_to_depth)).c_str()
                                : "no registration");
  ExpectRightOrNone(c, ro);
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
  // the scene this was found on: a far-off outline answer without the rule
  EXPECT_FALSE(ro.registration.ok) << ro.registration.reason;
  ASSERT_TRUE(w.registration.ok);
  EXPECT_EQ(w.method, "outlines");
  EXPECT_GT(CornerError(c, w.registration.photo_to_depth), 100.0);
  EXPECT_FALSE(f.registration.ok) << f.registration.reason;
  EXPECT_NE(f.registration.reason.find("arcs in view on edges"), std::string::npos) << f.registration.reason;
#endif
  AerialOptions bad;
  bad.outline_roof_veto_regions = -1;
  EXPECT_THROW(RegisterAerial(c.depth, c.photo, bad), Error);
}

// Small tiles (issue 21): with 2-4 outlines in view, poses that lay two
// sides of each roof on a road's kerbs or a crossing's stripes outscored the
// roofs. The outline search now weighs each pose by its completeness and
// scores the trees and hedges too (OutlineSearchOptions::completeness_power,
// object_weight; AerialOptions::outline_objects). Seed 130's small dense
// tile 8 (5 buildings, 200 x 200) and civic tile 9 (6 buildings) register
// only with both.
TEST(Aerial, SmallTilesRegisterByCompleteOutlinesAndTrees) {
  struct Case {
    const char* style;
    int buildings;
    std::uint64_t seed;
  };
  for (const Case& k : {Case{"dense", 5, 130000398u}, Case{"civic", 6, 130000399u}}) {
    CityOptions o;
    o.style = k.style;
    o.width = o.height = 200;
    o.trees = 4;
    o.buildings = k.buildings;
    const City c = MakeCity(o, k.seed);
    const AerialRegistration r = RegisterAerial(c.depth, c.photo);
    const AerialRegistration w = RegisterAerial(c.depth, c.photo, OutlineSearchBeforeCompleteness());
    std::printf("%s %llu: %s; without: %s\n", k.style, static_cast<unsigned long long>(k.seed),
                r.registration.ok ? cv::format("%s, %.2f px", r.method.c_str(), CornerError(c, r.registration.photo_to_depth)).c_str()
                                  : r.registration.reason.c_str(),
                w.registration.ok ? cv::format("%.2f px", CornerError(c, w.registration.photo_to_depth)).c_str() : "no registration");
    ExpectRightOrNone(c, r);
    ExpectRightOrNone(c, w);
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
    // the scenes this was measured on
    EXPECT_TRUE(r.registration.ok) << r.registration.reason;
    EXPECT_EQ(r.method, "outlines");
    EXPECT_FALSE(w.registration.ok);
#endif
  }
}

// One outline is no layout, for the image check either
// (OutlineSearchOptions::min_outlines). Seed 136's small civic tile 3: a
// 34 x 42 px photo (0.38 photo px per depth px) in which the search counts
// 2 outlines in view and the image check, sampling them more sparsely, 1,
// on edges at contrast 5.5. The pose was 52.6 px off; now there is none.
TEST(Aerial, AnOutlineAnswerNeedsTwoOutlinesInTheImageCheck) {
  CityOptions o;
  o.style = "civic";
  o.width = o.height = 200;
  o.trees = 4;
  const std::uint64_t seed = 136u * 1000003u + 3u;
  o.buildings = 3 + int(seed % 4);  // synth-city --buildings 3 --max-buildings 6
  const City c = MakeCity(o, seed);
  const AerialRegistration r = RegisterAerial(c.depth, c.photo);
  std::printf("photo %d x %d: %s\n", c.photo.cols, c.photo.rows,
              r.registration.ok ? cv::format("%s, %.2f px", r.method.c_str(), CornerError(c, r.registration.photo_to_depth)).c_str()
                                : r.registration.reason.c_str());
  ASSERT_LT(c.photo.cols * c.photo.rows, 60 * 60) << "not the scene this was measured on";
  ExpectRightOrNone(c, r);
}

TEST(Aerial, ImageCheckCanBeTurnedOff) {
  CityOptions o;
  o.width = o.height = 500;
  o.buildings = 16;
  const City c = MakeCity(o, 31);
  AerialOptions off;
  off.image_check = false;
  const AerialRegistration r = RegisterAerial(c.depth, c.photo, off);
  EXPECT_FALSE(r.registration.edge.enough);
}

TEST(Aerial, RejectsBadInput) {
  const cv::Mat1f depth(100, 100, 0.f);
  const cv::Mat3b photo(100, 100, cv::Vec3b(90, 90, 90));
  EXPECT_THROW(RegisterAerial(cv::Mat1f(), photo), Error);
  EXPECT_THROW(RegisterAerial(depth, cv::Mat()), Error);
  EXPECT_THROW(RegisterAerial(depth, cv::Mat(100, 100, CV_32FC3, cv::Scalar(0))), Error);
  AerialOptions bad;
  bad.photo_max_side = -1;
  EXPECT_THROW(RegisterAerial(depth, photo, bad), Error);
  bad = AerialOptions{};
  bad.outline_max_side = 10;  // 0 (off) or >= 64
  EXPECT_THROW(RegisterAerial(depth, photo, bad), Error);
  bad = AerialOptions{};
  bad.auto_outline_max_regions = -1;
  EXPECT_THROW(RegisterAerial(depth, photo, bad), Error);
  // a flat depth image: no buildings, an answer not an error
  const AerialRegistration flat = RegisterAerial(depth, photo);
  EXPECT_FALSE(flat.registration.ok);
  EXPECT_TRUE(flat.depth_regions.empty());
}

}  // namespace
}  // namespace mvkp
