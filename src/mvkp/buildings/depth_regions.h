// Building regions from a LiDAR depth image (thesis §7.2.1, "LiDAR
// segmentation"): the first component of the aerial photo <-> LiDAR
// registration (issue 8).
//
// Pipeline, as in the thesis (distances in depth pixels, heights in metres):
//  1. Range normalisation. Heights are taken relative to the local ground (a
//     grey-scale opening over ground_window pixels on the residual to a
//     best-fit plane, lifted to the mean of the near-ground pixels), so a DSM
//     with terrain and a slope works as well as an nDSM; that is the
//     "translate" of the thesis' translate-and-rescale normalisation. The
//     rescale is implicit: every test below is either in metres above ground
//     (WL) or relative to the current height (LCC), so a global scale factor
//     changes nothing.
//  2. Markers on a uniform grid (grid_step): per cell the highest pixel that is
//     above the water level WL and passes the local consistency check (LCC).
//     Cells on the ground or on trees get no marker.
//  3. Watershed-style region growing from each marker (highest pending pixel
//     first, i.e. flooding the negated depth image bottom-up; conditions are
//     tested when a pixel is taken from the queue). A pixel joins the region
//     unless one of the three boundary conditions holds:
//       a. it is below the dynamic water level: WL_dyn = WL once
//          area_cur >= area_min, else
//          WL_dyn = WL - (1 - exp(4 (area_cur - area_min) / area_min)) range_max
//          (the thesis' formula with the area in units of area_min / 4), so a
//          small region (e.g. a tower on a roof) is not stuck on its peak;
//       b. it is fully isolated along x or along y (both neighbours on that
//          axis fail (a)): a noise pixel outside the boundary. Partial
//          isolation (edge or corner points) does not stop growth;
//       c. it fails the LCC: over the disc of radius lcc_radius around the
//          pixel (height I_c), a neighbour at distance r is consistent when
//          |I - I_c| < T(r) = (1 - exp(-r^2 / (2 sigma^2))) I_c + lcc_noise
//          + r lcc_slope (stricter for closer pixels; the last term is not
//          in the thesis: the rise of a pitched roof, which the
//          height-relative term alone refuses on low houses, e.g. a 4 m
//          house with a 35 degree roof); the pixel passes when
//          #consistent >= P * Num. Num counts the neighbours with data above
//          the lowest dynamic water level: the ground beyond a roof edge is
//          the far side of a depth edge, not roof noise, so edges and corners
//          of roofs pass while noise-like tree crowns fail. A pixel with fewer
//          than lcc_min_support of the disc above that level fails. No 3-D
//          normals are computed.
//  4. Refinement: majority filling (>= 5 of 8 neighbours) of background pixels
//     in each region's bounding box (refine_iterations passes; the thesis
//     finds two enough).
//  5. Regions below min_area are dropped, and so are regions whose roughness
//     (median over the region of min(|second difference in x|, |... in y|))
//     exceeds max_roughness: an addition to the thesis for smooth dense
//     canopies that pass the LCC in patches (planar and pitched roofs, ridges
//     included, have roughness ~ noise). Duplicates (all four bounding-box
//     corners closer than merge_corner_px and areas within merge_area_ratio)
//     are merged.
//  6. The outer contour of each region is returned as a point list.
//
// Cost: O(pixels) with the default skip_covered_markers; 50-90 ms and ~15 MB
// for 1000 x 1000 on one core.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

struct BuildingRegion {
  std::vector<cv::Point> contour;  // outer contour, counter-clockwise as seen on the image
                                   // (x right, y down), i.e. shoelace sum < 0 in pixel
                                   // coordinates; every boundary pixel of the region
  cv::Rect bbox;                   // of the region, depth pixels
  double area = 0;                 // pixels inside the outer contour (holes filled)
  float height = 0;                // median height above local ground, metres
};

struct DepthSegmentOptions {
  // Range normalisation.
  bool estimate_ground = true;  // subtract a local ground estimate (DSM input); an nDSM
                                // gives ground ~ 0 and is unaffected
  int ground_window = 151;      // px; must exceed the smaller side of the largest building
  float nodata = -9999.f;       // depth values equal to this count as no data, like NaN
  // Markers.
  int grid_step = 8;            // px; one marker candidate per grid_step x grid_step cell
  // Water level and its dynamic range (boundary condition a).
  float water_level = 2.0f;     // WL, metres above ground: the lowest building of interest
  float range_max = 1.0f;       // range_MAX, metres: how far WL_dyn drops for tiny regions
  double area_min = 64;         // area_MIN, px: regions this large use WL_dyn = WL
  // Local consistency check (boundary condition c and marker condition 1).
  int lcc_radius = 3;           // px: outermost ring
  double lcc_sigma = 6.0;       // px: Gaussian of the ring thresholds T(r)
  double lcc_percent = 0.7;     // P: share of consistent neighbours needed
  float lcc_noise = 0.2f;       // metres added to T(r): LiDAR ranging noise
  float lcc_slope = 0.25f;      // metres per px of distance added to T(r): a pitched roof's rise
                                //   (at 0.5 m per px, 0.25 tolerates a 27 degree pitch by itself,
                                //   the height-relative term adds to it; 0: the thesis' LCC, which
                                //   missed 40 % of the houses of issue 21's suburb scenes)
  double lcc_min_support = 0.2; // fewer than this share of the disc above the
                                // low water level: isolated, fails the LCC
  // Region check (not in the thesis): canopies that pass the LCC in patches are
  // still rough where roofs are planar.
  float max_roughness = 0.2f;  // m; median min(|d2h/dx2|, |d2h/dy2|) over the region
  // Refinement and output.
  int refine_iterations = 2;    // majority-filling passes
  double min_area = 40;         // px; smaller regions are noise or unreliable
  double min_width_px = 5;      // px; narrower regions (widest inscribed disc) are hedges or
                                //   walls, not buildings (2.5 m at 0.5 m; 0: no check)
  double merge_corner_px = 3;   // duplicates: every bbox corner closer than this ...
  double merge_area_ratio = 0.05;  // ... and |area difference| <= this share of the larger
  bool skip_covered_markers = true;  // do not regrow from markers inside an earlier region
                                     // (a speed-up; merging catches what it would duplicate)
  void Check() const;           // throws Error(kInvalidArgument)
};

// Building regions of a depth image (metres; NaN or options.nodata = no data),
// largest first. labels (optional) receives a CV_32S map: 0 background, i + 1
// inside region i's outer contour (smaller regions drawn over larger ones).
// Throws Error(kBadImage) for an empty image or one without any data and
// Error(kInvalidArgument) for bad options. An image with nothing standing above
// the water level (flat, bare ground) gives no regions.
std::vector<BuildingRegion> SegmentDepth(const cv::Mat1f& depth, const DepthSegmentOptions& options = {},
                                         cv::Mat1i* labels = nullptr, cv::Mat1f* above_ground = nullptr);

// What stands above the ground besides the buildings: trees, hedges, sheds,
// walls. Their outlines are evidence a photo shows too (issue 21: a tile of 3-6
// buildings puts 2-3 outlines in a photo, too few to tell the pose from the
// roads and markings that line up with them by chance).
struct ObjectOutlineOptions {
  float min_height = 1.0f;   // m above the local ground
  double min_area = 12;      // px; smaller blobs are cars, noise or single returns
  int building_margin = 2;   // px around every building region left out (its walls, its lean)
  void Check() const;        // throws Error(kInvalidArgument)
};

// Outer contours (depth px) of the connected areas of `above_ground` (metres
// above the local ground, NaN = no data: SegmentDepth's) standing at least
// min_height, outside the `regions` (dilated by building_margin), of at least
// min_area px.
std::vector<std::vector<cv::Point>> ObjectOutlines(const cv::Mat1f& above_ground, const std::vector<BuildingRegion>& regions,
                                                   const ObjectOutlineOptions& options = {});

// Colour drawing for `mvkp segment depth --draw`: the depth as grey levels
// (no data dark red), each region tinted in its own colour with its contour.
// CV_8UC3, the size of depth.
cv::Mat DrawRegions(const cv::Mat1f& depth, const std::vector<BuildingRegion>& regions);

}  // namespace mvkp
