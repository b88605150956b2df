// Input layer of the aerial photo <-> LiDAR registration (thesis ch. 7, issue 8):
// depth images from GeoTIFF DSM/nDSM (GDAL) or LAS point clouds, and optical
// (aerial) images from anything OpenCV or GDAL reads.
//
// Conventions. A depth image is a float raster of heights in metres, NaN where
// there is no data, row 0 at the north (top) edge. Its optional georeference is
// a GDAL geotransform of pixel CORNERS: the ground point of pixel (col, row),
// measured at its top-left corner, is
//   X = geo[0] + col * geo[1] + row * geo[2],  Y = geo[3] + col * geo[4] + row * geo[5],
// so the centre of pixel (c, r) is at (c + 0.5, r + 0.5). Heights and ground
// units are taken as metres (projected CRS in metres or feet; see res_m).
//
// Every failure a user can cause throws mvkp::Error naming the file:
// kIo for a missing or unreadable file, kBadImage for content we cannot use
// (not a raster, LAZ, truncated or inconsistent LAS, absurd sizes, nodata
// everywhere, flat depth), kInvalidArgument for out-of-range options.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "mvkp/core/image_io.h"

namespace mvkp::geo {

struct DepthRaster {
  cv::Mat1f z;                    // heights, metres; NaN where there is no data
  double res_m = 0;               // ground size of a pixel, metres; 0 if unknown (no or geographic georeference)
  std::array<double, 6> geo{};    // GDAL geotransform (x0, dx, rx, y0, ry, dy) of pixel corners, if has_geo
  bool has_geo = false;
  std::string crs_wkt;            // CRS as WKT; may be empty
};

// Rasterising an uncompressed LAS 1.0-1.4 file (point formats 0-10).
struct LasRasterOptions {
  double res_m = 0.5;             // ground size of a cell, metres (CRS units)
  double fill_max_gap_m = 3.0;    // empty regions up to this wide are filled (see FillDepthHoles); 0: no filling
  int max_side = 20000;           // the grid may be at most this many cells per side (memory: 4 bytes a cell)
  bool drop_noise = true;         // skip withheld points and classes 7 (low noise) and 18 (high noise)
  void Check() const;             // throws Error(kInvalidArgument)
};

struct DepthReadOptions {
  LasRasterOptions las;           // used when the file is LAS
  int max_side = 20000;           // GDAL rasters: at most this many pixels per side
  double min_relief_m = 0.5;      // the valid heights must span at least this much (else "flat depth"); 0: no check
  void Check() const;             // throws Error(kInvalidArgument)
};

// Reads a depth image: LAS (by the "LASF" signature or a .las extension) is
// rasterised with RasteriseLas(path, options.las); LAZ (.laz extension, or the
// compression bit / laszip VLR in a LAS header) is rejected with a
// "decompress first" message; anything else goes through GDAL (GeoTIFF DSM or
// nDSM, ESRI ASCII grid, VRT, ...): band 1, GDAL's nodata / mask -> NaN,
// band scale/offset applied. Then checks that some data is left and that it
// is not flat (options.min_relief_m).
DepthRaster ReadDepthRaster(const std::string& path, const DepthReadOptions& options = {});

// Rasterises a LAS file to a max-Z depth image: the grid is aligned to
// multiples of res_m, covers every kept point, row 0 at the largest Y;
// a cell's height is the highest kept point in it; holes are then filled with
// FillDepthHoles(z, fill_max_gap_m / res_m). crs_wkt comes from an OGC WKT VLR
// when present (GeoTIFF-key VLRs are not converted). Validates the header
// (signature, version, sizes, record length against the point format, point
// counts against the file size, scales) before reading any point; never reads
// past the end of the file. No flatness check (ReadDepthRaster does that).
DepthRaster RasteriseLas(const std::string& path, const LasRasterOptions& options = {});

// The same for a LAS file held in memory (`size` bytes at `data`, e.g. an
// upload); `name` stands for the file in error messages. The same checks
// apply, so no input makes it read outside those bytes.
DepthRaster RasteriseLasBytes(const std::string& name, const std::uint8_t* data, std::size_t size,
                              const LasRasterOptions& options = {});

// Fills holes (NaN cells) in place with the height of the nearest valid cell.
// A hole is a connected (8-neighbour) region of NaN cells; its width is taken
// as 2 d - 1 cells, d being the largest distance (cells) from its cells to the
// nearest valid one; holes wider than max_gap_px stay NaN entirely, so large
// gaps (water, missing coverage) are not invented. Returns the number of cells
// filled. Nearest-neighbour (not smooth) filling keeps roof edges sharp.
int FillDepthHoles(cv::Mat1f& z, double max_gap_px);

struct OpticalImage {
  cv::Mat bgr;                    // CV_8UC3
  double res_m = 0;               // ground size of a pixel, as DepthRaster::res_m
  std::array<double, 6> geo{};    // as DepthRaster::geo
  bool has_geo = false;
  std::string crs_wkt;
};

// Reads an aerial image as 8-bit BGR. PNG, JPEG, PNM, BMP and WebP go through
// mvkp::LoadImageColor (strict: truncated data is an error); TIFF is tried
// there first, and TIFF or any other format falls back to GDAL (multi-band
// GeoTIFF, VRT, JPEG 2000, ...): bands 1,2,3 taken as R,G,B, one band (or
// gray+alpha) as gray; non-8-bit data is stretched between its 0.5 and 99.5
// percentiles. The georeference (GeoTIFF tags, world files) comes from GDAL
// whenever it can open the file.
OpticalImage ReadOpticalImage(const std::string& path, const ImageLimits& limits = {});

}  // namespace mvkp::geo
