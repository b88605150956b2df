// A pseudo-nadir view of an oblique photo (issue 22, for feature fusion):
// the view turned, by a rotation about its camera centre, to look straight
// down. Not in the thesis, which describes the oblique view as it is; but
// shape contexts are invariant to rotation and scale only, and a roof seen
// 30-60 degrees off nadir is foreshortened by up to a half and in true
// perspective. After the rotation every horizontal plane (roofs, ground)
// is a similarity of the nadir photo's (each with its own parallax shift),
// which is what the descriptors can match.
//
// The rotation needs the direction "down" in the camera frame. The camera
// is taken as upright (no roll: the horizon level in the view, as oblique
// aerial cameras are mounted) and its tilt off nadir as a hypothesis; the
// caller tries a few tilts and keeps the one whose features agree best.
// (The vanishing point of vertical edges would give down directly, roll
// included, but on the generated cities facade edges are too few and too
// short against the road grid: the point with the most support was the
// true one in 0 of 4 views tried.)
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace mvkp {

struct RectifyOptions {
  // Rays farther than this from "down" are left out (towards the horizon
  // the rectified view stretches without bound).
  double max_ray_deg = 75;
  double scale = 1;             // rectified px per view px at the view's centre... roughly: the focal length's factor
  int max_side = 2048;          // the rectified view's longer side at most
  void Check() const;           // throws Error(kInvalidArgument)
};

struct Rectification {
  double tilt_deg = 0;      // the hypothesis
  cv::Vec3d down;           // unit vector, camera frame (x right, y down, z forward)
  cv::Matx33d H;            // view px -> rectified px
  cv::Size size;            // of the rectified view
};

// The rectification of a view of `size` with intrinsics K, for an upright
// camera tilted `tilt_deg` off nadir (in [0, 89)).
Rectification RectifyForTilt(cv::Size size, const cv::Matx33d& K, double tilt_deg, const RectifyOptions& options = {});

// The view warped by r.H (BGR or grey; outside the view: black, which the
// region growing takes for shadow).
cv::Mat Rectify(const cv::Mat& view, const Rectification& r);

}  // namespace mvkp
