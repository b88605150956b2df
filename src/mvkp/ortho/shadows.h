// Cast-shadow compensation for nadir aerial photos (issue 21; not in the
// thesis, whose shadow map is a fixed dark threshold, §7.2.2).
//
// A cast shadow takes the sun away and leaves the sky: every channel drops
// by the same factor wherever the shadow falls, and blue drops least
// (skylight is bluer than sunlight). In log colour a shadow is therefore one
// fixed step d = (d_B, d_G, d_R), all negative, with d_B > d_R. Shadows cut
// roofs and ground into pieces and put their outer edge (shadow to lit
// ground), a stronger edge than the roof's own, beside every roof; the
// region and edge routes of the registration then fail or err towards the
// sun (docs/aerial.md, "Shadows: what they cost").
//
// Pipeline:
//  1. The step, from the photo itself: across Canny edges whose two sides
//     (edge_offset px away along the gradient) are locally uniform, the log
//     colour difference dark minus bright; the densest mode (mean shift)
//     among those that darken every channel by at least min_step on
//     average, blue least and red most (tint (d_B - d_R) / |mean| >=
//     min_tint, d_B >= d_G >= d_R up to 0.02). Material
//     edges scatter; shadow edges repeat the same step. Too few votes: no
//     step, nothing changes (grey shadows, which no colour test can tell
//     from dark materials, are left alone).
//  2. Seeds: a pixel whose colour, lit again (minus d), matches a pixel on
//     rings around it within match_eps in every channel: the same material,
//     in and out of the shadow. Precise at shadow borders (~95 % on
//     generated suburbs), blind in wide shadows' interiors.
//  3. Growth from the seeds into neighbours that look like the shadow near
//     them (within grow_tol of the mask's mean colour over a grow_window
//     window, and not brighter than it by more than grow_up): the interiors.
//     The window anchors the test, so the growth does not creep up a
//     penumbra's ramp into the lit ground.
//  4. Relighting: the photo divided by the step over the (feathered) mask.
//
// Measured (docs/aerial.md, "Shadow compensation: a fallback pass"), seed
// 122 suburb, 40 scenes: 27 registered as the photos are; 36 with the
// photos relit by the TRUE shadow mask (so relighting is the right remedy);
// 33 with this detector given the generator's own step (a prototype); 25-29
// with the step found in the photo, as here, by variant. Dark materials
// whose colour ratio to a neighbour mimics the step (asphalt beside paving,
// dark grass patches) are relit too. So it does not go first (enabled is
// false by default); the registration uses it as a second pass where the
// photo as it is finds nothing (AerialOptions::shadow_fallback).
//
// Memory: about 14 bytes a working-photo pixel besides the photo and its
// relit copy (the log colours, the mask and the growth's pass map);
// everything else runs in bands of rows.
#pragma once
#include <opencv2/core.hpp>

namespace mvkp {

struct ShadowOptions {
  bool enabled = false;         // false: the photo passes unchanged (callers turn it on; see "Measured")
  int work_max_side = 0;        // the step, seeds and growth on the photo downscaled to this side (0: never);
                                //   the relighting at full size
  // --- the step (calibration)
  double pre_blur_sigma = 1.0;  // Gaussian smoothing before the log colours
  cv::Vec3d log_step{0, 0, 0};  // the step, when known (every channel < 0): no calibration
  int edge_offset = 4;          // px either side of an edge where its two colours are read, or up to 2 px
                                //   farther where both sides are uniform there (coarse photos'
                                //   shadows are a few px wide); the first that passes the tests below
  int side_window = 5;          // ... each side locally uniform: the sd of log intensity in this square
  double max_side_sd = 0.04;    //   below this
  double min_step = 0.2;        // a candidate darkens every channel by >= 0.1 and by >= this on average (log)
  double min_tint = 0.3;        // (d_B - d_R) / |mean d| at least this: blue drops least
  double mode_window = 0.06;    // mean-shift window (max over channels, log)
  int min_votes = 40;           // edge samples in the step's mode, at least
  int max_samples = 20000;      // edge samples read, at most (evenly strided)
  // --- seeds
  double match_eps = 0.05;      // relit colour vs a ring pixel, max over channels (log)
  int ring_dirs = 16;           // directions per ring; rings at 3, 6, 10 and 16 px
  // --- growth
  double grow_tol = 0.06;       // max over channels from the mask's local mean colour (log)
  int grow_window = 15;         // side of the window of that mean, px
  double grow_up = 0.03;        // not brighter (mean log) than that mean by more than this
  int grow_rounds = 12;         // each round may grow up to grow_window / 2 px
  // --- result
  double max_fraction = 0.4;    // a mask above this fraction of the photo is not shadows: nothing changes
  double feather_sigma = 1.0;   // the mask's soft edge when relighting
  void Check() const;           // throws Error(kInvalidArgument)
};

struct ShadowCompensation {
  bool applied = false;         // a step was found and the photo relit
  cv::Vec3d log_step{0, 0, 0};  // d = log(shadowed / lit) per channel, B G R (when found)
  int votes = 0;                // edge samples in the step's mode
  int samples = 0;              // edge samples that darken with a blue tint
  double fraction = 0;          // of the photo's pixels relit
  double ms = 0;
};

// The 8-bit BGR photo with its cast shadows relit (a copy; the input is not
// changed). A grey or empty image, ShadowOptions::enabled false, or a photo
// where no step is found, comes back unchanged (same data). mask (optional):
// 255 where relit. Throws Error(kBadImage) for a non-8-bit image.
cv::Mat CompensateShadows(const cv::Mat& bgr, const ShadowOptions& o = {}, ShadowCompensation* info = nullptr,
                          cv::Mat1b* mask = nullptr);

}  // namespace mvkp
