// Oblique views of a synthetic city, with exact ground truth (issue 22, thesis §7.3).
//
// Stage 2 of the aerial pipeline registers oblique photos (cameras 30-60° off
// nadir that see facades) to the nadir photo, and through stage 1 to the
// LiDAR. RenderOblique() photographs a City (synth_city.h) with a pinhole
// camera at any tilt and azimuth:
//   - the surface is the city's DSM (NaN gaps filled from their nearest
//     return), ray-marched per pixel, so buildings and trees occlude what is
//     behind them;
//   - roofs, ground and tree crowns take their colour from the nadir photo
//     (where a point at height z shows in a leaning orthophoto);
//   - facades are the DSM's walls, with a colour per building, rows of
//     windows every 3 m and Lambert shading by the city's sun;
//   - then a lighting change (gain, gamma, tint), blur, noise and JPEG.
// The ground truth is the 3x4 camera matrix from world metres to oblique
// pixels and check points (roof corners, open ground) that the camera sees,
// each with its depth, nadir-photo and oblique pixel.
//
// World frame: east, north, up (right-handed, so that the camera is a proper
// rotation and PnP can recover it): x = depth column * res_m, y = -depth row
// * res_m, z = the DSM's height in metres. Depth pixel centres are at
// integers, as in synth_city.h; pixel (c, r) is world (c * res, -r * res).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/city/synth_city.h"

namespace mvkp {

struct ObliqueOptions {
  double tilt_deg = 45;        // optical axis off nadir, [0, 75]
  double azimuth_deg = 0;      // direction the camera looks, clockwise from north (up in the depth raster)
  double gsd_m = 0.3;          // ground sampling distance at the image centre across the view, m / px
  int width = 1024, height = 768;
  double hfov_deg = 50;        // horizontal field of view
  cv::Point2d target{-1, -1};  // depth px seen at the image centre; negative: the nadir photo's centre
  double lighting = 0.2;       // max relative gain / gamma change from the nadir photo
  double blur = 0.8;           // max blur sigma, px
  double noise = 3.0;          // max noise sigma, grey levels
  int jpeg_quality = 85;       // 0: no JPEG round trip
  int check_points = 300;      // candidate check points (roof corners first, then open ground)
  void Check() const;          // throws Error(kInvalidArgument) naming the first bad option
};

struct ObliqueCheckPoint {
  cv::Point3d world;      // metres
  cv::Point2d depth_px;   // (x, -y) / res_m
  cv::Point2d nadir_px;   // where the nadir photo shows it (its lean included)
  cv::Point2d oblique_px; // camera * world
  int building = -1;      // roof corner of this building; -1: open ground
};

struct ObliqueView {
  cv::Mat3b image;                 // BGR
  cv::Matx34d camera;              // world metres -> oblique px (pixel centres at integers)
  cv::Matx33d K, R;                // camera = K [R | -R C]
  cv::Vec3d centre_m;              // C
  cv::Mat1i building_id;           // per pixel: building whose roof or facade it shows, else -1
  std::vector<ObliqueCheckPoint> checks;  // visible check points inside the image and the nadir photo
  ObliqueOptions options;
  std::uint64_t seed = 0;
};

// Renders one oblique view of `city`. Throws mvkp::Error on bad options or
// when the camera would sit below the city.
ObliqueView RenderOblique(const City& city, const ObliqueOptions& options, std::uint64_t seed);

// Writes dir/<stem>.png (the view) and dir/<stem>.json (camera, K, R, C,
// options, check points). Throws Error(kIo) when a file cannot be written.
void SaveOblique(const ObliqueView& view, const std::string& dir, const std::string& stem);

// How far `camera` (world metres -> view px) is from the truth: the mean
// distance between its projections of the view's check points and their
// true pixels (the evaluation's measure; success is <= 5 px). Infinity
// for a view without check points or a point behind the camera.
double CheckPointError(const cv::Matx34d& camera, const ObliqueView& view);

}  // namespace mvkp
