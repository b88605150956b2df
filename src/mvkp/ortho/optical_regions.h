// Building (roof) regions from a nadir aerial PHOTO (thesis §7.2.2), for
// shape matching against building regions of a LiDAR depth image (§7.2.3).
//
// Pipeline (each step behind an option):
//  1. Assistant information maps (AIMs) on the lightly smoothed photo:
//     vegetation (green dominant, in absolute terms AND relative to the
//     brightness: a few % colour cast must not turn a white roof into
//     "vegetation"), shadow (I < T1 and max(B,G,R) < T2), and a
//     Canny edge map whose pixels are split into TRUE edges and IN-REGION
//     edges: an edge pixel is in-region when the nearest non-edge pixels on
//     both sides across it (horizontal or vertical pair, chosen by the
//     gradient direction) have similar hue (HSV; for unsaturated pixels,
//     where hue is undefined, similar intensity instead).
//  2. Selective smoothing: each in-region edge pixel takes the mean colour of
//     its non-edge 8-neighbours.
//  3. Seeds on a uniform grid; a cell centre failing the seed conditions
//     (not vegetation, shadow, edge, already labelled, natural texture) is
//     replaced by the centres of its four sub-cells.
//  4. Region growing (4-connected) under the expansion requirements: fractal
//     error (OFE >= ofe_ratio * natural level of the fBm model; the OFE map is
//     computed for the whole photo with box filters, which is cheaper than the
//     thesis's on-demand evaluation), vegetation / shadow maps, true edges as
//     barriers, in-region edges passable with an uncertainty penalty, and the
//     dynamic intensity range [L, U] with tolerance T_range (softened while
//     the region is below min_area, stricter when the pixel's colour
//     preference differs from the seed's) and a cap on U - L. Not in the
//     thesis: a pixel whose colour preference is a different non-zero colour
//     is rejected outright, and its chromaticity must stay near the region's
//     mean (max_chroma_step); these stop leaks into same-intensity ground.
//  5. Uncertainty per pixel UPP = (1 + DIR / range_len) * #IREP / area;
//     small or high-UPP segments are dropped.
//  6. Region merging of adjacent candidates whose shared border is mostly not
//     a true edge and whose chromaticity is close (e.g. the two shaded halves
//     of a pitched roof).
//  7. Region regulation: LDA on the peak-neighbourhood ratios of the x/y
//     contour histograms (ortho_models.h; laxer for outlines cut by the photo
//     border), plus simple shape sanity (area, elongation, solidity). Not in
//     the thesis: a region more elongated than max_elongation_unshaded must
//     show cast-shadow evidence in its outer ring (raised objects cast
//     shadows, road and kerb pieces do not); optional and off by default:
//     thin-structure suppression, a rectilinearity test, a hard shadow-ring
//     requirement (each measured and found to cost more roofs than it saves
//     false regions on generated cities, see bench/ortho_eval.cc).
//
// Contours are outer boundaries in photo pixel coordinates (pixel centres at
// integers), COUNTER-CLOCKWISE AS SEEN ON SCREEN (x right, y down): the
// shoelace sum over (x, y) is negative, i.e. cv::contourArea(c, true) < 0.
// They start at the point of smallest y (then smallest x), as in §7.2.3.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/ortho/ortho_models.h"

namespace mvkp {

struct PhotoRegion {
  std::vector<cv::Point> contour;  // outer, CCW on screen, photo px
  cv::Rect bbox;                   // bounding box of the contour
  double area = 0;                 // contour area, px²
  double confidence = 0;           // in (0, 1]: exp(-UPP / upp_scale) of the region
  double upp = 0;                  // uncertainty per pixel (§7.2.2)
  double lda_score = 0;            // region-regulation score (> 0: regular)
  int color_preference = 0;        // 0 none, 1 blue, 2 green, 3 red dominant (of the seed)
};

struct OpticalSegmentOptions {
  // --- preprocessing / AIMs
  double pre_blur_sigma = 1.0;       // Gaussian smoothing before everything except the fractal error; 0: none
  int thin_suppress = 0;             // (not in the thesis) grey opening + closing with this square before the
                                     // maps: erases structures thinner than it (road markings, seams, tile
                                     // rows, roof equipment) so they neither cut regions nor make edges; 0: off
  bool use_vegetation = true;        // vegetation map blocks growth
  int veg_green_margin = 8;          // vegetation: G >= R + margin, G >= B - 2 (shaded foliage is bluish) ...
  int veg_exg = 14;                  // ... and excess green 2G - R - B >= veg_exg
  double veg_exg_rel = 0.1;          // ... and (2G - R - B) / (B + G + R) >= this (not in the thesis: a colour
                                     // cast of a few % makes bright grey roofs pass the absolute tests); 0: off
  bool use_shadow = true;            // shadow map blocks growth (thesis: relaxable in dense cities)
  int shadow_intensity = 60;         // T_shadow1: intensity below
  int shadow_channel = 80;           // T_shadow2: max(B, G, R) below
  int canny_low = 40, canny_high = 100;  // Canny thresholds on the smoothed colour photo
  bool split_edges = true;           // tell in-region from true edges by hue; false: all edges are true edges
  int edge_probe = 3;                // search distance (px) for the non-edge pixels across an edge
  int hue_similar = 8;               // max hue difference (OpenCV hue, 0..180) for "similar"
  int sat_min_for_hue = 40;          // below this saturation (0..255) compare intensity instead of hue
  int gray_similar = 22;             // max intensity difference for unsaturated pixels
  bool selective_smoothing = true;   // replace in-region edge pixels by their non-edge neighbours' mean
  int barrier_dilate = 0;            // dilate true edges by this many px (closes gaps; contours compensate)
  // --- seeds
  int seed_cell = 16;                // grid cell side, px; failing centres fall back to four sub-cells
  // --- region growing
  bool use_fractal = true;           // fractal-error expansion requirement
  FbmModel fbm;                      // natural-texture model; invalid: fitted on this photo's vegetation map
                                     // (test skipped when that has < ~5000 px)
  double ofe_ratio = 0.6;            // pass if OFE >= ofe_ratio * fbm.ofe (conservative: admits false positives)
  int range_tolerance = 10;          // T_range: how far a pixel may lie outside [L, U]
  int range_tolerance_strict = 3;    // T_range when the pixel's colour preference differs from the region's
  int range_soft_max = 12;           // Range_max: extra tolerance while area < min_area
  int range_len = 48;                // cap on U - L (dynamic intensity range length)
  double max_chroma_step = 0.1;      // (not in the thesis) reject pixels whose chromaticity (b,g,r)/(b+g+r) is
                                     // farther (L1) from the region's mean than this; 0: off
  int color_margin = 14;             // colour preference: channel exceeds both others by this much
  double irep_penalty = 1.0;         // weight of an in-region edge pixel in the uncertainty
  // --- candidates
  int min_area = 120;                // px; smaller segments are dropped
  double max_area_fraction = 0.2;    // segments above this fraction of the photo are ground, not roofs
  double max_upp = 0.25;             // candidates with larger uncertainty per pixel are dropped
  double upp_scale = 0.1;            // confidence = exp(-UPP / upp_scale)
  // --- merging
  bool merge = true;                 // merge adjacent candidates (pitched-roof halves, over-segmentation)
  int merge_gap = 2;                 // regions up to this many px apart count as adjacent
  double merge_min_contact = 0.35;   // shared border >= this * sqrt(smaller area)
  double merge_max_true_edge = 0.35; // at most this fraction of the shared border on true edges
  double merge_max_chroma = 0.05;    // max L1 distance of mean chromaticity (b, g, r)/(b+g+r)
  // --- regulation
  bool regulate = true;              // LDA region regulation on contour PNRs
  RegionLda lda;                     // invalid: DefaultRegionLda()
  double lda_margin = -0.25;         // keep if score > lda_margin (conservative: only clearly irregular outlines go)
  double lda_border_relax = 1.0;     // margin lowered by this for outlines cut by the photo border (>= 5 % of points)
  double max_elongation = 6;         // min-area-rect long/short side above: road, not roof
  double min_rectilinear = 0.0;      // (not in the thesis) length fraction of the polygonised outline (±10°)
                                     // along its two dominant perpendicular directions below: natural blob; 0: off
  double min_shadow_ring = 0.0;      // (not in the thesis) raised objects cast shadows: keep only regions whose
                                     // 5-px outer ring has at least this fraction of "dark" pixels (below
                                     // shadow_ring_ratio x the ring's median); 0: off (it costs many roofs)
  double shadow_ring_ratio = 0.7;
  double max_elongation_unshaded = 3;  // (not in the thesis) elongation limit for regions whose ring has fewer
                                     // than shadow_ring_evidence dark pixels: a long strip without a cast
                                     // shadow is a road / kerb piece; long buildings keep max_elongation
  double shadow_ring_evidence = 0.2;
  double min_solidity = 0.55;        // area / convex hull area below: irregular clutter
  int contour_dilate = 1;            // grow final masks by this many px (regions stop 1 px inside edges)
  void Check() const;                // throws Error(kInvalidArgument)
};

// Roof regions of an 8-bit BGR (or grey) nadir photo, best first (by
// confidence). labels (optional): the final region index + 1 per pixel, 0
// elsewhere. Throws Error(kBadImage) for an empty or non-8-bit image.
std::vector<PhotoRegion> SegmentOptical(const cv::Mat& bgr, const OpticalSegmentOptions& opt = {},
                                        cv::Mat1i* labels = nullptr);
// The same, consuming `bgr`: its pixels are released (when no other Mat
// shares them) once the working maps are built, which lowers peak memory by
// the photo's size.
std::vector<PhotoRegion> SegmentOptical(cv::Mat&& bgr, const OpticalSegmentOptions& opt = {},
                                        cv::Mat1i* labels = nullptr);

// Debug view of the assistant maps: vegetation green, shadow blue, true edges
// red, in-region edges yellow, seeds white, over the dimmed photo.
cv::Mat DrawOpticalMaps(const cv::Mat& bgr, const OpticalSegmentOptions& opt = {});

// The photo with each region's contour drawn in its own colour.
cv::Mat DrawPhotoRegions(const cv::Mat& bgr, const std::vector<PhotoRegion>& regions);

}  // namespace mvkp
