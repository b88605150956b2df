// Views of a planar target as a pinhole camera sees them: the target plane at
// a tilt from any azimuth, any roll, at the distance that makes its longest
// side span a given number of pixels, somewhere in the frame. True
// perspective (not an affine approximation), so steep views foreshorten the
// far edge as a phone camera does.
//
// Two users: the training views (a virtual camera around the target, tilt up
// to ~80°, sampled ASIFT-style) and the sweep benchmark's test frames
// (`mvkp eval sweep`), which add a real background photo, lighting, blur,
// noise and JPEG, and render by supersampling rather than by the trainer's
// warp, so that the test does not share the trainer's resampling.
#pragma once

#include <array>
#include <cstdint>

#include <opencv2/core.hpp>

namespace mvkp {

struct CameraPose {
  double tilt_deg = 0;     // angle between the plane's normal and the ray to the target's centre, [0, 89]
  double azimuth_deg = 0;  // direction (in the target plane) of the axis the plane is tilted about
  double roll_deg = 0;     // rotation of the target about the viewing ray
  double size_px = 320;    // longest side of the target's outline in the frame (pixels)
  double hfov_deg = 62;    // the camera's horizontal field of view
  // Where the ray to the target's centre meets the frame (pixels); negative:
  // the frame's centre.
  cv::Point2d centre{-1, -1};
  void Check() const;  // throws mvkp::Error(kInvalidArgument)
};

// The homography (target pixels -> frame pixels, pixel centres at integer
// coordinates) of a target of `target` size seen by a camera with a frame of
// `frame` size in `pose`. The distance is solved so that the longest edge of
// the projected outline is pose.size_px (to 0.1 %).
cv::Matx33d CameraHomography(cv::Size target, cv::Size frame, const CameraPose& pose);

// The target's corners (0,0), (w-1,0), (w-1,h-1), (0,h-1) under H.
std::array<cv::Point2d, 4> OutlineUnder(const cv::Matx33d& H, cv::Size target);

// Longest edge of a quadrilateral (pixels).
double LongestEdge(const std::array<cv::Point2d, 4>& quad);

// The smallest and largest local linear scale of H's Jacobian at point p
// (singular values): how much H stretches the target there in its most and
// least compressed directions.
cv::Vec2d LocalScales(const cv::Matx33d& H, cv::Point2d p);

struct CameraSceneOptions {
  int width = 640, height = 480;            // frame size
  double min_hfov = 55, max_hfov = 70;      // field of view drawn from this range (degrees)
  bool fit = true;                          // place the target wholly inside the frame where it fits
  double min_gain = 0.45, max_gain = 1.3;   // target contrast (lighting on the target)
  double max_offset = 30;                   // target brightness offset (grey levels)
  double gradient = 0.25;                   // frame-wide illumination ramp, +/- this fraction
  double max_blur = 1.2;                    // Gaussian sigma drawn from [0, max_blur] (a quarter of the views: motion blur instead)
  double min_noise = 1, max_noise = 5;      // Gaussian noise sigma (grey levels)
  int jpeg_quality = 85;                    // 0: no JPEG round trip
  int supersample = 4;                      // render at this factor, then area-average (a sensor's pixels integrate)
  void Check() const;
};

struct CameraScene {
  cv::Mat image;          // BGR (or grey when the target is grey), width x height
  cv::Matx33d H;          // target pixels -> frame pixels
  CameraPose pose;        // the pose used (hfov and centre filled in)
  bool inside = true;     // whole outline within the frame
};

// A busy synthetic backdrop (textured noise and random filled shapes, high
// contrast), reproducible from the seed: for test frames when no real photo
// is at hand (the target quality score).
cv::Mat MakeClutterBackground(cv::Size size, std::uint64_t seed, bool colour = false);

// One test frame: a random crop of `background` (any size, BGR or grey;
// empty: a flat grey), the target in `pose` (its hfov is drawn from the
// options' range and its centre is chosen so the outline fits, when
// options.fit), then lighting, blur, noise and JPEG. Reproducible from `seed`.
CameraScene MakeCameraScene(const cv::Mat& target, const cv::Mat& background, CameraPose pose,
                            const CameraSceneOptions& options, std::uint64_t seed);

}  // namespace mvkp
