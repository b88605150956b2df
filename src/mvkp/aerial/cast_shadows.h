// Cast shadows predicted from the depth (issue 21; docs/aerial.md, "Shadows
// cast by the depth"). The photo-only detector (ortho/shadows.h) must tell
// a shadow from a dark material by colour alone, and relights asphalt and
// dark grass too. At a candidate pose the depth says where shadows can be:
// a building of height h on flat ground casts the sweep of its footprint
// along the anti-sun direction u, over h * k depth px, with k = 1 /
// (tan(sun elevation) * depth resolution) depth px per metre.
//
//  1. The sun, fitted to the photo at the pose (downscaled to fit_max_side):
//     for every anti-sun azimuth (azimuths, evenly) and length factor k
//     (lengths, log-spaced in [min_length, max_length]), the predicted
//     shadows S (outside every roof and footprint) against the ring R just
//     beyond them (ring_px wide, outside roofs too); the score is the
//     darkness mean_R(log Y) - mean_S(log Y). Right sun: S dark, R lit.
//     Too short: R still in shadow; too long, or another azimuth: S lit.
//     Coarse to fine: every azimuth at every third length, then (when that
//     comes near standing out) every length about the best azimuth.
//  2. Refused (nothing relit) unless the best score reaches min_contrast and
//     stands clear of the other azimuths (at the same k) by min_margin over
//     the median other azimuth's score, at a length below the longest tried
//     (an optimum at the bound is no length found). A wrong pose or a photo
//     of other ground gives no azimuth that stands out.
//  3. The step per channel (log colour, B G R): the shadow's dark pixels
//     minus the ring, each channel.
//  4. Relit: the predicted shadows at the working size, grown by grow_px
//     depth px for the pose's error, where a pixel is darker than its lit
//     surroundings (the ring's local mean) by at least half the step;
//     (I + 4) * exp(-step * feathered mask) - 4, as ortho/shadows.cc does;
//     nothing changes when the mask would exceed max_fraction of the photo.
//
// Only the buildings the depth segmented cast shadows here (not trees), on
// flat ground. Deterministic. Cost: 10-100 ms a candidate pose for the fit
// (most wrong poses stop after the coarse stage), 20-60 ms to relight a
// 1200 px photo.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/buildings/depth_regions.h"

namespace mvkp {

struct CastShadowOptions {
  int fit_max_side = 400;        // the sun fit on the photo downscaled to this side (px)
  int azimuths = 36;             // anti-sun directions tried, evenly over 360 deg
  int lengths = 10;              // length factors tried, log-spaced ...
  double min_length = 0.3;       // ... from this (depth px of shadow per metre of height) ...
  double max_length = 8.0;       // ... to this (sun at 15-75 deg, depth px of 0.25-1 m)
  double min_height_m = 2.5;     // buildings lower than this cast nothing counted
  int min_buildings = 3;         // buildings in view needed to fit a sun
  double ring_px = 2.0;          // width of the lit ring beyond the shadows (fit px)
  double min_contrast = 0.15;    // darkness of the shadows against the ring (log), at least
  double min_margin = 0.15;      // ... and above the median other azimuth's by this (log)
  double grow_px = 2.0;          // the relit mask grown by this for the pose's error (depth px)
  double feather_sigma = 1.0;    // the mask's soft edge (working px)
  double max_fraction = 0.3;     // a relit mask above this share of the photo is not shadows: nothing changes
  void Check() const;            // throws Error(kInvalidArgument)
};

struct CastShadowFit {
  bool found = false;            // a sun was fitted (steps 1-3)
  bool applied = false;          // ... and the photo relit
  std::string reason;            // why not, when !applied
  int buildings = 0;             // buildings in view that cast shadows
  double azimuth_deg = 0;        // the shadows' direction in the depth raster, clockwise from up (north)
  double length_px_per_m = 0;    // k above
  double contrast = 0;           // the best score (log)
  double margin = 0;             // ... minus the median other azimuth's
  cv::Vec3d log_step{0, 0, 0};   // d = log(shadowed / lit), B G R
  double fraction = 0;           // of the working photo relit
  double ms = 0;
};

// The 8-bit BGR `photo` (the working photo: full-size photo px * f = its
// px) relit where the depth's `buildings` cast shadows at the pose
// `photo_to_depth` (full-size photo px -> depth px, the ground) with the
// photo's `lean` (depth px per metre of height, roofs only). Returns the
// photo unchanged (same data) when no sun is fitted. Grey photos: unchanged.
// Steps 1-3 only: the sun at that pose (found, or why not). For choosing
// among candidate poses: a right pose's shadows stand out.
CastShadowFit FitCastShadows(const cv::Mat& photo, double f, const cv::Matx33d& photo_to_depth, cv::Point2d lean,
                             const std::vector<BuildingRegion>& buildings, const CastShadowOptions& options = {});

cv::Mat RelightCastShadows(const cv::Mat& photo, double f, const cv::Matx33d& photo_to_depth, cv::Point2d lean,
                           const std::vector<BuildingRegion>& buildings, const CastShadowOptions& options = {},
                           CastShadowFit* fit = nullptr);

}  // namespace mvkp
