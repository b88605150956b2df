// Synthetic cities for aerial photo <-> LiDAR registration (issue 8, thesis §7).
//
// MakeCity() builds one scene: a LiDAR-like depth raster (DSM, metres, NaN where
// the LiDAR gave no return) and an aerial photo of the same city, related by a
// known homography. The city has a road grid with markings and cars, blocks of
// grass or pavement, buildings with rectilinear and irregular footprints
// (rectangles, L, T, U, courtyards, chamfered/notched, some rotated off the grid)
// with flat, gable or hip roofs and roof equipment, and trees that are noisy in
// depth (LiDAR penetrates canopies) and green in the photo.
//
// The photo is first rendered as a true orthophoto of the ground (roof colours
// and textures, roof shading by the sun, cast shadows, road markings), then
// warped by a random rotation (full circle), scale (photo pixel -> depth pixel,
// log-uniform in [min_scale, max_scale]), translation and mild perspective, and
// finally blurred and noised like a sensor. The city continues beyond the depth
// raster, so a photo that only partly overlaps it (or, with overlap = false,
// not at all) still shows plausible content everywhere.
//
// Everything is reproducible from the seed: std::mt19937_64 with our own
// uniform/normal sampling, and cv::RNG (OpenCV's own generator) for noise fields.
//
// Styles (CityOptions::style, issue 21). "classic" is the generator above, unchanged
// byte for byte. The others are towns of a different make, for testing on data the
// registration was not tuned on; all of them add sloped, undulating ground (metres
// across the tile), cars that moved between the LiDAR and the photo flights, dark
// roofs with few returns, and a conventional (not true) orthophoto: everything above
// the ground is displaced in the photo by height x a lean vector, with the facades on
// one side visible as a band.
//   suburb: one or two street grids (the second rotated); detached houses with gable,
//           hip, shed or flat roofs, gardens with hedges (tall in depth, green in the
//           photo), swimming pools (blue; no return in depth, like water) and sheds.
//   dense:  apartment bars, L/T/U blocks and courtyards, towers, commercial halls with
//           parking lots full of cars, flat roofs with equipment.
//   civic:  round buildings with domed roofs and star-shaped buildings among suburb
//           and dense buildings.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

struct CityOptions {
  int width = 1000, height = 1000;  // depth raster size (pixels)
  int buildings = 30;               // buildings inside the depth raster (fewer if they do not fit)
  double res_m = 0.5;               // depth raster ground resolution (metres per pixel)
  int trees = 60;                   // trees inside the depth raster (more outside, at the same density)
  double min_scale = 0.3;           // photo pixel -> depth pixel scale, log-uniform in [min, max]
  double max_scale = 3.0;
  double max_perspective = 0.1;     // max relative change of the projective divisor over the photo (0: similarity)
  double sun_azimuth_deg = -1;      // clockwise from north (= up in the depth raster); < 0: random
  double sun_elevation_deg = -1;    // < 0: random in [30, 65]
  double missing_returns = 0.01;    // fraction of depth pixels set to NaN, in small patches
  double depth_noise_m = 0.05;      // Gaussian LiDAR range noise (sigma, metres)
  double ground_slope = 0.01;       // max terrain slope (rise/run); the depth is a DSM
  int photo_max_side = 2000;        // longest photo side (pixels); low scales cover less ground
  double min_coverage = 0.5;        // ground side the photo covers, as a fraction of the
  double max_coverage = 1.2;        //   depth raster's longest side (before the photo_max_side cap)
  bool overlap = true;              // false: the photo shows a different area (negative tests)
  bool pitched_roofs = true;        // gable/hip roofs on small buildings
  double photo_blur = 0.8;          // max sensor blur sigma (photo pixels)
  double photo_noise = 4.0;         // max sensor noise sigma (grey levels)
  std::string style = "classic";    // classic | suburb | dense | civic (see above)
  // Throws mvkp::Error(kInvalidArgument) naming the first bad option.
  void Check() const;
};

enum class RoofType { kFlat = 0, kGable = 1, kHip = 2, kShed = 3, kDome = 4 };
const char* RoofTypeName(RoofType r);  // "flat", "gable", "hip", "shed", "dome"

// The styles CityOptions::style accepts, in order.
const std::vector<std::string>& CityStyles();

struct City {
  cv::Mat1f depth;                 // DSM in metres (ground ~0, mild slope); NaN = no return
  cv::Mat3b photo;                 // BGR aerial photo
  cv::Matx33d photo_to_depth;      // ground truth: photo pixel -> depth pixel (pixel centres at integers)
  // Buildings inside the depth raster, index = building id:
  std::vector<std::vector<cv::Point2f>> footprints;         // outer outline, depth pixels
  std::vector<std::vector<std::vector<cv::Point2f>>> holes;  // courtyards (inner rings), depth pixels
  std::vector<cv::Point2f> corners;                          // all outline vertices, depth pixels
  std::vector<double> heights_m;                             // eave height above ground
  std::vector<RoofType> roofs;
  std::vector<std::string> shapes;                           // "rect", "L", "T", "U", "courtyard", "irregular"
                                                             // (+ "round", "star" in the civic style)
  std::vector<cv::Vec3b> roof_colours;                       // base roof colour in the photo (BGR)
  cv::Mat1i building_id;           // per depth pixel: building index or -1
  cv::Mat1i photo_building_id;     // per photo pixel: building index, -1 none, -2 a building outside the depth raster
  cv::Mat1b photo_road_mask;       // per photo pixel: 255 on a road or its sidewalks (for scoring segmentations)
  cv::Mat1b tree_mask;             // per depth pixel: 255 where a tree canopy is
  // Scene parameters (ground truth for analysis):
  double scale = 1;                // depth pixels per photo pixel at the photo centre
  double rotation_deg = 0;         // in-plane rotation of the photo, [0, 360)
  cv::Point2d perspective{0, 0};   // projective row (p1, p2) of the photo, per photo pixel from its centre
  double sun_azimuth_deg = 0, sun_elevation_deg = 0;
  double photo_overlap = 0;        // fraction of the photo that shows the depth raster's ground
  double depth_overlap = 0;        // fraction of the depth raster the photo shows
  int outside_buildings = 0;       // buildings drawn in the photo outside the depth raster
  // Styles other than classic (zero / empty for classic):
  cv::Point2d lean{0, 0};          // photo displacement of a point h metres up: h * lean metres (depth axes)
  std::vector<std::vector<cv::Point2f>> pools;  // swimming pools inside the depth raster (NaN in depth), depth px
  int minor_structures = 0;        // sheds: small buildings not counted in footprints
  int parking_lots = 0;            // parking lots (dense and civic halls)
  double ground_range_m = 0;       // max - min of the terrain over the depth raster (metres)
  CityOptions options;
  std::uint64_t seed = 0;
};

// One synthetic scene, reproducible from (options, seed). Throws mvkp::Error on bad options.
City MakeCity(const CityOptions& options, std::uint64_t seed);

// Writes dir/depth.tif (32-bit float TIFF, NaN = no return; read with
// cv::imread(..., IMREAD_UNCHANGED)), dir/photo.png, dir/truth.json (H, corners,
// footprints, holes, heights, roofs, options, seed, ...), dir/depth_preview.png
// (colour map, no-return black) and dir/building_id.png (16-bit, id + 1, 0 = none).
// `stem` is prefixed to the file names ("" -> depth.tif, "a" -> a_depth.tif).
// Creates dir. Throws mvkp::Error(kIo) when a file cannot be written.
void SaveCity(const City& city, const std::string& dir, const std::string& stem = "");

// Fraction of the photo that maps into the depth raster (by H, sampled on a grid).
double PhotoOverlap(const cv::Matx33d& photo_to_depth, cv::Size photo, cv::Size depth);

}  // namespace mvkp
