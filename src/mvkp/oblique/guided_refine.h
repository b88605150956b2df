// Guided refinement of an oblique view's camera (issue 22, stage 2).
//
// The camera from the tiles' matches (view_pose.h) is held by points where
// MVKP found tiles, often a few patches of the view: its error grows away
// from them, and views whose pairs cluster land 5-6 px off at the far side
// (held-back seed 111: three answers of 5.6-6.0 px, RMS 1.8-2.3 px).
//
// Here the camera itself predicts where corners of the nadir photo appear.
// Each corner on a flat, visible patch of roof or ground is warped from the
// nadir photo into the view by the homography of its horizontal plane
// (stage 1 to the depth, the lean shifted by its height, the camera), and
// found again by normalised cross-correlation within a few pixels of the
// prediction. These pairs come from all over the view, with sub-pixel
// positions; the camera is refitted on the ones that agree.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/oblique/view_pose.h"

namespace mvkp {

struct GuidedRefineOptions {
  int max_corners = 4000;        // Shi-Tomasi corners of the nadir photo
  double corner_spacing_px = 5;  // between them, nadir px
  // A corner is used only where the DSM within a radius (nadir px, up to
  // flat_radius_px) of it spans at most max_height_step_m, and its template
  // in the view covers no more than that: the patch is then one horizontal
  // plane, which one homography maps.
  double flat_radius_px = 8;
  double max_height_step_m = 0.5;
  int max_tries = 800;           // corners tried per view (spread evenly)
  int search_px = 12;            // search radius around the prediction, view px
  double min_ncc = 0.8;          // correlation of an accepted match
  double min_contrast = 6;       // template grey-level standard deviation
  double inlier_px = 2.0;        // residual of a pair the refit keeps
  int min_pairs = 30;            // fewer: the first camera is kept
  // Share of the first camera's inliers the refitted one must keep within
  // keep_first_px: it may correct them (a camera held by a few patches is
  // biased, and its own inliers with it: on tuning seed 4 a 4.4 px camera
  // kept 11 of its 26 within 4 px once refined to 0.3 px), but not leave
  // them beyond the search radius.
  double keep_first = 0.7;
  double keep_first_px = 12.0;
  void Check() const;            // throws Error(kInvalidArgument)
};

struct GuidedRefinement {
  bool refined = false;  // the camera was refitted
  int tried = 0;         // corners predicted inside the view, visible and textured
  int found = 0;         // matched by correlation
  int inliers = 0;       // kept by the refit
  double rms_px = 0;     // of those
  double shift_px = 0;   // mean move of the kept pairs' predictions, first -> refined camera
};

// Precomputed corners of a nadir photo (8-bit grey) on flat surfaces, and
// the refinement of cameras against it.
class GuidedRefiner {
 public:
  // `lifter`: stage 1 of the same photo (used here, not kept).
  GuidedRefiner(const cv::Mat& nadir_gray, const NadirLifter& lifter, const GuidedRefineOptions& options = {});

  // Refines `pose` (ok) of `view` (8-bit grey, intrinsics K) in place, with
  // the same `lifter` as at construction; `world` / `pixels`: the pairs the
  // pose was found from (pose->inlier flags them). The pose keeps its first
  // camera when too few pairs agree, or when the refitted camera loses the
  // first one's inliers (a refit that walked away).
  GuidedRefinement Refine(const cv::Mat& view, const cv::Matx33d& K, const NadirLifter& lifter,
                          const std::vector<cv::Point3d>& world, const std::vector<cv::Point2d>& pixels,
                          ViewPose* pose) const;

  std::size_t corners() const { return corners_.size(); }

 private:
  struct Corner {
    cv::Point2f nadir;
    cv::Point3d world;
    double above_m;
    double flat_px;  // radius (nadir px) within which the DSM is flat
  };
  GuidedRefineOptions options_;
  cv::Mat nadir_, half_;  // the photo, and its half-size level (views coarser than it)
  std::vector<Corner> corners_;
};

}  // namespace mvkp
