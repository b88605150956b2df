// Depth and optical rasters through GDAL, hole filling, format dispatch.
#include "mvkp/geo/raster.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>
#include <gdal_frmts.h>
#include <ogr_srs_api.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp::geo {
namespace {

namespace fs = std::filesystem;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

[[noreturn]] void Bad(const std::string& path, const std::string& what) {
  throw Error(ErrorCode::kBadImage, path + ": " + what);
}

std::string Lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

void CheckFile(const std::string& path) {
  if (path.rfind("/vsi", 0) == 0) return;  // GDAL virtual file systems
  std::error_code ec;
  Require(fs::exists(path, ec), ErrorCode::kIo, path + ": no such file");
  Require(fs::is_regular_file(path, ec), ErrorCode::kIo, path + ": not a regular file");
  Require(std::ifstream(path, std::ios::binary).good(), ErrorCode::kIo, path + ": cannot open for reading");
}

// GDAL's own messages are collected (not printed) while one of these lives;
// the handler stack is per thread.
class GdalQuiet {
 public:
  GdalQuiet() {
    // GeoTIFF only at first: registering all ~200 drivers touches ~11 MB of
    // GDAL's pages (the issue-8 memory budget); Open() adds the rest when a
    // file needs them.
    static std::once_flag once;
    std::call_once(once, [] { GDALRegister_GTiff(); });
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~GdalQuiet() { CPLPopErrorHandler(); }
  GdalQuiet(const GdalQuiet&) = delete;
  GdalQuiet& operator=(const GdalQuiet&) = delete;
  static std::string Last() {
    const char* m = CPLGetLastErrorMsg();
    return m && *m ? std::string(": ") + m : std::string();
  }
};

struct GdalClose {
  void operator()(void* ds) const { GDALClose(static_cast<GDALDatasetH>(ds)); }
};
using Dataset = std::unique_ptr<void, GdalClose>;

Dataset Open(const std::string& path) {
  Dataset ds(GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr));
  if (!ds) {
    static std::once_flag all;
    bool registered = false;
    std::call_once(all, [&] { GDALAllRegister(), registered = true; });
    if (registered) {
      CPLErrorReset();
      ds.reset(GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr));
    }
  }
  return ds;
}

// Geotransform, CRS and metres per pixel of an open dataset.
void ReadGeo(GDALDatasetH ds, std::array<double, 6>& geo, bool& has_geo, double& res_m, std::string& crs_wkt) {
  double gt[6];
  has_geo = false;
  res_m = 0;
  if (GDALGetGeoTransform(ds, gt) == CE_None) {
    const double det = gt[1] * gt[5] - gt[2] * gt[4];
    has_geo = std::all_of(gt, gt + 6, [](double v) { return std::isfinite(v); }) && std::isfinite(det) && det != 0;
    if (has_geo) {
      std::copy(gt, gt + 6, geo.begin());
      res_m = std::sqrt(std::fabs(det));
    }
  }
  if (OGRSpatialReferenceH srs = GDALGetSpatialRef(ds)) {
    char* wkt = nullptr;
    if (OSRExportToWkt(srs, &wkt) == OGRERR_NONE && wkt) crs_wkt = wkt;
    CPLFree(wkt);
    if (OSRIsGeographic(srs)) res_m = 0;               // degrees: no metric pixel size
    else if (OSRIsProjected(srs)) res_m *= OSRGetLinearUnits(srs, nullptr);  // e.g. feet -> metres
  }
}

// Reads band b (1-based) as float with GDAL's mask (nodata, alpha, ...) as NaN
// and the band's scale/offset applied.
cv::Mat1f ReadBandFloat(const std::string& path, GDALDatasetH ds, int b, int w, int h) {
  GDALRasterBandH band = GDALGetRasterBand(ds, b);
  if (!band) Bad(path, "cannot access band " + std::to_string(b) + GdalQuiet::Last());
  if (GDALDataTypeIsComplex(GDALGetRasterDataType(band))) Bad(path, "complex-valued raster (not a depth or image band)");
  cv::Mat1f z(h, w);
  if (GDALRasterIO(band, GF_Read, 0, 0, w, h, z.ptr(), w, h, GDT_Float32, 0, 0) != CE_None)
    Bad(path, "cannot read band " + std::to_string(b) + " (corrupt or truncated?)" + GdalQuiet::Last());
  int has_scale = 0, has_offset = 0;
  const double scale = GDALGetRasterScale(band, &has_scale), offset = GDALGetRasterOffset(band, &has_offset);
  if ((has_scale && scale != 1) || (has_offset && offset != 0))
    z.convertTo(z, CV_32F, has_scale ? scale : 1.0, has_offset ? offset : 0.0);
  if (!(GDALGetMaskFlags(band) & GMF_ALL_VALID)) {
    GDALRasterBandH mask_band = GDALGetMaskBand(band);
    cv::Mat1b mask(h, w);
    if (!mask_band || GDALRasterIO(mask_band, GF_Read, 0, 0, w, h, mask.ptr(), w, h, GDT_Byte, 0, 0) != CE_None)
      Bad(path, "cannot read the nodata mask of band " + std::to_string(b) + GdalQuiet::Last());
    z.setTo(kNaN, mask == 0);
  }
  for (int y = 0; y < h; ++y) {
    float* row = z[y];
    for (int x = 0; x < w; ++x)
      if (!std::isfinite(row[x])) row[x] = kNaN;
  }
  return z;
}

DepthRaster ReadGdalDepth(const std::string& path, const DepthReadOptions& options) {
  GdalQuiet quiet;
  Dataset ds = Open(path);
  if (!ds) Bad(path, "not a depth raster GDAL or the LAS reader can read" + GdalQuiet::Last());
  GDALDatasetH d = ds.get();
  const int w = GDALGetRasterXSize(d), h = GDALGetRasterYSize(d);
  if (GDALGetRasterCount(d) < 1 || w <= 0 || h <= 0) Bad(path, "the raster has no pixels");
  if (w > options.max_side || h > options.max_side)
    Bad(path, "raster size " + std::to_string(w) + "x" + std::to_string(h) + " exceeds max_side " +
                  std::to_string(options.max_side));
  // Three or four 8-bit bands are a colour picture, not heights: a photo
  // passed as the depth image (the arguments swapped, say).
  const int bands = GDALGetRasterCount(d);
  if (bands >= 3 && GDALGetRasterDataType(GDALGetRasterBand(d, 1)) == GDT_Byte)
    Bad(path, "a " + std::to_string(bands) + "-band 8-bit image looks like a photo, not depth: give a DSM/nDSM "
              "(one band of heights) or a LAS file");
  DepthRaster out;
  out.z = ReadBandFloat(path, d, 1, w, h);
  ReadGeo(d, out.geo, out.has_geo, out.res_m, out.crs_wkt);
  return out;
}

bool StartsWithLasf(const std::string& path) {
  char m[4] = {};
  std::ifstream in(path, std::ios::binary);
  return in.read(m, 4) && std::memcmp(m, "LASF", 4) == 0;
}

// Byte percentile stretch of float bands (NaN ignored) to 8 bits.
std::vector<cv::Mat> StretchTo8(const std::string& path, const std::vector<cv::Mat1f>& bands) {
  std::vector<float> v;
  for (const cv::Mat1f& b : bands)
    for (float f : cv::Mat_<float>(b.reshape(1, 1)))
      if (!std::isnan(f)) v.push_back(f);
  if (v.empty()) Bad(path, "the image is nodata everywhere");
  const auto at = [&](double q) {
    auto it = v.begin() + std::ptrdiff_t(q * double(v.size() - 1));
    std::nth_element(v.begin(), it, v.end());
    return double(*it);
  };
  const double lo = at(0.005), hi = at(0.995);
  const double s = hi > lo ? 255.0 / (hi - lo) : 0.0;
  std::vector<cv::Mat> out;
  for (const cv::Mat1f& b : bands) {
    cv::Mat1b m;
    b.convertTo(m, CV_8U, s, -lo * s);  // saturating; NaN -> 0
    out.push_back(m);
  }
  return out;
}

cv::Mat ReadGdalOptical(const std::string& path, GDALDatasetH d, const ImageLimits& limits) {
  const int w = GDALGetRasterXSize(d), h = GDALGetRasterYSize(d), n = GDALGetRasterCount(d);
  if (n < 1 || w <= 0 || h <= 0) Bad(path, "the image has no pixels");
  if (w > limits.max_side || h > limits.max_side || std::int64_t(w) * h > limits.max_pixels)
    Bad(path, "image size " + std::to_string(w) + "x" + std::to_string(h) + " exceeds the limit (" +
                  std::to_string(limits.max_side) + " px per side, " + std::to_string(limits.max_pixels) + " pixels)");
  if (w < limits.min_side || h < limits.min_side)
    Bad(path, "image is " + std::to_string(w) + "x" + std::to_string(h) + ", smaller than the minimum " +
                  std::to_string(limits.min_side));
  const std::vector<int> rgb = n >= 3 ? std::vector<int>{1, 2, 3} : std::vector<int>{1};
  bool all_byte = true;
  for (int b : rgb) all_byte = all_byte && GDALGetRasterDataType(GDALGetRasterBand(d, b)) == GDT_Byte;
  std::vector<cv::Mat> planes;
  if (all_byte) {
    for (int b : rgb) {
      cv::Mat1b m(h, w);
      if (GDALRasterIO(GDALGetRasterBand(d, b), GF_Read, 0, 0, w, h, m.ptr(), w, h, GDT_Byte, 0, 0) != CE_None)
        Bad(path, "cannot read band " + std::to_string(b) + " (corrupt or truncated?)" + GdalQuiet::Last());
      planes.push_back(m);
    }
  } else {
    std::vector<cv::Mat1f> f;
    for (int b : rgb) f.push_back(ReadBandFloat(path, d, b, w, h));
    planes = StretchTo8(path, f);
  }
  cv::Mat bgr;
  if (planes.size() == 1) cv::cvtColor(planes[0], bgr, cv::COLOR_GRAY2BGR);
  else cv::merge(std::vector<cv::Mat>{planes[2], planes[1], planes[0]}, bgr);
  return bgr;
}

}  // namespace

void DepthReadOptions::Check() const {
  las.Check();
  Require(max_side > 0, ErrorCode::kInvalidArgument, "depth raster: max_side must be > 0");
  Require(std::isfinite(min_relief_m) && min_relief_m >= 0, ErrorCode::kInvalidArgument,
          "depth raster: min_relief_m must be >= 0");
}

DepthRaster ReadDepthRaster(const std::string& path, const DepthReadOptions& options) {
  options.Check();
  CheckFile(path);
  const std::string ext = Lower(fs::path(path).extension().string());
  DepthRaster out = ext == ".las" || ext == ".laz" || StartsWithLasf(path) ? RasteriseLas(path, options.las)
                                                                           : ReadGdalDepth(path, options);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::int64_t valid = 0;
  for (int y = 0; y < out.z.rows; ++y)
    for (int x = 0; x < out.z.cols; ++x) {
      const float v = out.z(y, x);
      if (std::isnan(v)) continue;
      ++valid;
      lo = std::min(lo, double(v));
      hi = std::max(hi, double(v));
    }
  if (valid == 0) Bad(path, "no data: every one of the " + std::to_string(out.z.total()) + " cells is nodata");
  if (hi - lo < options.min_relief_m)
    Bad(path, "flat depth: the heights span only " + std::to_string(hi - lo) + " m (" + std::to_string(lo) + " to " +
                  std::to_string(hi) + "), less than min_relief_m " + std::to_string(options.min_relief_m) +
                  "; no structure to register");
  return out;
}

int FillDepthHoles(cv::Mat1f& z, double max_gap_px) {
  Require(!std::isnan(max_gap_px) && max_gap_px >= 0, ErrorCode::kInvalidArgument,
          "FillDepthHoles: max_gap_px must be >= 0");
  if (z.empty() || max_gap_px < 1) return 0;
  cv::Mat1b holes(z.size());
  std::int64_t n_holes = 0;
  for (int y = 0; y < z.rows; ++y)
    for (int x = 0; x < z.cols; ++x) {
      const bool hole = std::isnan(z(y, x));
      holes(y, x) = hole ? 255 : 0;
      n_holes += hole;
    }
  if (n_holes == 0 || n_holes == std::int64_t(z.total())) return 0;
  // Distance of every hole cell to the nearest valid cell, and which cell that is.
  cv::Mat1f dist;
  cv::Mat1i nearest;
  cv::distanceTransform(holes, dist, nearest, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
  std::vector<float> value_of(z.total() - std::size_t(n_holes) + 1, kNaN);
  for (int y = 0; y < z.rows; ++y)
    for (int x = 0; x < z.cols; ++x)
      if (!holes(y, x) && nearest(y, x) >= 0 && std::size_t(nearest(y, x)) < value_of.size())
        value_of[std::size_t(nearest(y, x))] = z(y, x);
  cv::Mat1i comp;
  const int n_comp = cv::connectedComponents(holes, comp, 8, CV_32S);
  std::vector<float> reach(std::size_t(n_comp), 0.f);
  for (int y = 0; y < z.rows; ++y)
    for (int x = 0; x < z.cols; ++x)
      if (holes(y, x)) reach[std::size_t(comp(y, x))] = std::max(reach[std::size_t(comp(y, x))], dist(y, x));
  int filled = 0;
  for (int y = 0; y < z.rows; ++y)
    for (int x = 0; x < z.cols; ++x) {
      if (!holes(y, x) || 2.0 * reach[std::size_t(comp(y, x))] - 1.0 > max_gap_px) continue;
      const int label = nearest(y, x);
      if (label < 0 || std::size_t(label) >= value_of.size()) continue;
      z(y, x) = value_of[std::size_t(label)];
      filled += !std::isnan(z(y, x));
    }
  return filled;
}

OpticalImage ReadOpticalImage(const std::string& path, const ImageLimits& limits) {
  CheckFile(path);
  std::uint8_t head[32] = {};
  std::size_t n_head = 0;
  {
    std::ifstream in(path, std::ios::binary);
    in.read(reinterpret_cast<char*>(head), sizeof head);
    n_head = std::size_t(in.gcount());
  }
  if (n_head == 0) Bad(path, "empty file");
  std::string format = "unknown";
  try {
    format = ReadImageHeader(path, head, n_head).format;
  } catch (const Error&) {
    format = "damaged";  // LoadImageColor below reports it
  }
  OpticalImage out;
  std::string opencv_error;
  GdalQuiet quiet;
  if (format != "tiff" && format != "unknown") {
    out.bgr = LoadImageColor(path, limits);  // strict decoders; throws on failure
  } else if (format == "tiff") {
    try {
      out.bgr = LoadImageColor(path, limits);
    } catch (const Error& e) {
      if (e.code() == ErrorCode::kIo) throw;  // no GDAL fallback for an unreadable file
      opencv_error = std::string(" (OpenCV: ") + e.what() + ")";
    }
  }
  // A PNG/JPEG/PNM/BMP carries a georeference only in a sidecar file (world
  // file or .aux.xml); without one GDAL has nothing to add (and opening it
  // would register every driver: ~7 MB of resident pages).
  auto has_sidecar = [&] {
    const fs::path p(path);
    std::string ext = p.extension().string();
    if (ext.size() >= 3) ext = std::string(".") + ext[1] + ext.back() + "w";  // .png -> .pgw
    std::error_code ec;
    for (const fs::path& side : {fs::path(path + ".aux.xml"), fs::path(p).replace_extension(ext),
                                 fs::path(path + "w"), fs::path(p).replace_extension(".wld")})
      if (fs::exists(side, ec)) return true;
    return false;
  };
  Dataset ds;
  if (out.bgr.empty() || format == "tiff" || format == "unknown" || has_sidecar()) ds = Open(path);
  if (out.bgr.empty()) {
    if (!ds) Bad(path, "not an image OpenCV or GDAL can read" + GdalQuiet::Last() + opencv_error);
    out.bgr = ReadGdalOptical(path, ds.get(), limits);
  }
  if (ds && GDALGetRasterXSize(ds.get()) == out.bgr.cols && GDALGetRasterYSize(ds.get()) == out.bgr.rows)
    ReadGeo(ds.get(), out.geo, out.has_geo, out.res_m, out.crs_wkt);
  return out;
}

}  // namespace mvkp::geo
