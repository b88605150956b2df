// LAS 1.0-1.4 reader (ASPRS LAS specification R15), uncompressed only, and its
// max-Z rasterisation. Only what a depth image needs is decoded: the public
// header, the VLR headers (laszip detection, OGC WKT) and X, Y, Z,
// classification and the withheld flag of each point record.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "mvkp/core/error.h"
#include "mvkp/geo/raster.h"

namespace mvkp::geo {
namespace {

namespace fs = std::filesystem;

// Point record sizes of formats 0-10 without extra bytes.
constexpr int kMinRecordLength[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
constexpr std::uint64_t kChunkBytes = 4u << 20;  // point data is streamed in chunks of about this size

[[noreturn]] void Bad(const std::string& path, const std::string& what) {
  throw Error(ErrorCode::kBadImage, path + ": " + what);
}

std::uint16_t U16(const unsigned char* p) { return std::uint16_t(p[0] | p[1] << 8); }
std::uint32_t U32(const unsigned char* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
std::uint64_t U64(const unsigned char* p) { return std::uint64_t(U32(p)) | std::uint64_t(U32(p + 4)) << 32; }
std::int32_t I32(const unsigned char* p) { return std::int32_t(U32(p)); }
double F64(const unsigned char* p) {
  const std::uint64_t u = U64(p);
  double d;
  std::memcpy(&d, &u, sizeof d);
  return d;
}

std::string Lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

[[noreturn]] void LazError(const std::string& path) {
  const fs::path p(path);
  const std::string out = Lower(p.extension().string()) == ".laz"
                              ? fs::path(p).replace_extension(".las").string()
                              : fs::path(p).replace_extension("").string() + "_decompressed.las";
  throw Error(ErrorCode::kBadImage, path + ": LAZ (compressed LAS) is not supported; decompress first, e.g. `pdal translate " +
                                        path + " " + out + "` or `laszip -i " + path + " -o " + out + "`");
}

struct LasHeader {
  int major = 0, minor = 0;
  std::uint32_t header_size = 0, point_offset = 0, num_vlrs = 0;
  int format = 0;
  std::uint32_t record_length = 0;
  std::uint64_t count = 0;
  double scale[3] = {}, offset[3] = {};
  std::string crs_wkt;
};

// The bytes of a LAS file: streamed from a file, or in memory.
class LasSource {
 public:
  LasSource(std::ifstream& in, std::uint64_t size) : in_(&in), size_(size) {}
  LasSource(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint64_t size() const { return size_; }

  // Reads exactly n bytes at pos or throws "truncated".
  void ReadAt(const std::string& path, std::uint64_t pos, void* dst, std::size_t n, const std::string& what) {
    if (!in_) {
      if (pos > size_ || n > size_ - pos) Bad(path, "truncated file: cannot read " + what);
      if (n) std::memcpy(dst, data_ + pos, n);
      return;
    }
    in_->clear();
    in_->seekg(std::streamoff(pos));
    in_->read(static_cast<char*>(dst), std::streamsize(n));
    if (!*in_ || std::size_t(in_->gcount()) != n) Bad(path, "truncated file: cannot read " + what);
  }

 private:
  std::ifstream* in_ = nullptr;
  const std::uint8_t* data_ = nullptr;
  std::uint64_t size_ = 0;
};

LasHeader ReadHeader(LasSource& in, const std::string& path) {
  const std::uint64_t fsize = in.size();
  if (fsize < 4) Bad(path, "not a LAS file (" + std::to_string(fsize) + " bytes)");
  unsigned char h[375] = {};
  const std::size_t got = std::size_t(std::min<std::uint64_t>(fsize, sizeof h));
  in.ReadAt(path, 0, h, got, "the header");
  if (std::memcmp(h, "LASF", 4) != 0) Bad(path, "not a LAS file (no \"LASF\" signature)");
  if (got < 227) Bad(path, "truncated LAS header (" + std::to_string(got) + " of at least 227 bytes)");

  LasHeader L;
  L.major = h[24];
  L.minor = h[25];
  // The compression bits come first: a LAZ file must get the LAZ message.
  const int format_byte = h[104];
  if (format_byte & 0x80 || format_byte & 0x40) LazError(path);
  if (L.major != 1 || L.minor > 4)
    Bad(path, "unsupported LAS version " + std::to_string(L.major) + "." + std::to_string(L.minor) + " (1.0-1.4 are read)");
  L.header_size = U16(h + 94);
  L.point_offset = U32(h + 96);
  L.num_vlrs = U32(h + 100);
  L.format = format_byte;
  L.record_length = U16(h + 105);
  const std::uint32_t need_header = L.minor >= 4 ? 375 : L.minor == 3 ? 235 : 227;
  if (L.header_size < need_header)
    Bad(path, "header size " + std::to_string(L.header_size) + " is smaller than LAS 1." + std::to_string(L.minor) +
                  " requires (" + std::to_string(need_header) + ")");
  if (L.header_size > fsize) Bad(path, "truncated file: the header size " + std::to_string(L.header_size) + " exceeds the file size");
  if (L.point_offset < L.header_size)
    Bad(path, "point data offset " + std::to_string(L.point_offset) + " lies inside the header (" +
                  std::to_string(L.header_size) + " bytes)");
  if (L.point_offset > fsize)
    Bad(path, "truncated file: point data offset " + std::to_string(L.point_offset) + " is past the end of the file (" +
                  std::to_string(fsize) + " bytes)");
  if (L.format > 10) Bad(path, "unknown point data format " + std::to_string(L.format) + " (0-10 exist)");
  if (L.format >= 6 && L.minor < 4)
    Bad(path, "point data format " + std::to_string(L.format) + " needs LAS 1.4, the header says 1." + std::to_string(L.minor));
  if (L.record_length < std::uint32_t(kMinRecordLength[L.format]))
    Bad(path, "point record length " + std::to_string(L.record_length) + " is smaller than point format " +
                  std::to_string(L.format) + " needs (" + std::to_string(kMinRecordLength[L.format]) + " bytes)");

  const std::uint64_t legacy = U32(h + 107);
  L.count = legacy;
  if (L.minor >= 4) {
    const std::uint64_t extended = U64(h + 247);
    if (extended != 0 && legacy != 0 && extended != legacy)
      Bad(path, "inconsistent point counts: legacy " + std::to_string(legacy) + ", LAS 1.4 " + std::to_string(extended));
    if (extended != 0) L.count = extended;
  }
  if (L.count == 0) Bad(path, "the header declares no points");
  const std::uint64_t avail = fsize - L.point_offset;
  if (L.count > avail / L.record_length)
    Bad(path, "truncated file: the header declares " + std::to_string(L.count) + " points of " +
                  std::to_string(L.record_length) + " bytes but only " + std::to_string(avail) +
                  " bytes follow the point data offset");

  for (int i = 0; i < 3; ++i) {
    L.scale[i] = F64(h + 131 + 8 * i);
    L.offset[i] = F64(h + 155 + 8 * i);
    if (!std::isfinite(L.scale[i]) || L.scale[i] == 0 || !std::isfinite(L.offset[i]))
      Bad(path, std::string("bad ") + "XYZ"[i] + " scale/offset in the header (scale must be finite and non-zero)");
  }

  // VLRs: each a 54-byte header + payload, all before the point data.
  std::uint64_t pos = L.header_size;
  for (std::uint32_t i = 0; i < L.num_vlrs; ++i) {
    if (pos + 54 > L.point_offset)
      Bad(path, "variable length record " + std::to_string(i + 1) + " of " + std::to_string(L.num_vlrs) +
                    " runs past the point data offset");
    unsigned char v[54];
    in.ReadAt(path, pos, v, sizeof v, "a variable length record");
    const std::string user(reinterpret_cast<const char*>(v + 2), strnlen(reinterpret_cast<const char*>(v + 2), 16));
    const int record_id = U16(v + 18);
    const std::uint64_t len = U16(v + 20);
    if (pos + 54 + len > L.point_offset)
      Bad(path, "variable length record " + std::to_string(i + 1) + " runs past the point data offset");
    if (user == "laszip encoded" && record_id == 22204) LazError(path);
    if (user == "LASF_Projection" && record_id == 2112 && len > 0) {
      std::string wkt(len, '\0');
      in.ReadAt(path, pos + 54, wkt.data(), len, "the WKT record");
      wkt.resize(strnlen(wkt.c_str(), wkt.size()));
      L.crs_wkt = wkt;
    }
    pos += 54 + len;
  }
  return L;
}

// Calls f(x, y, z) for every point that passes the filter, streaming the file.
template <class F>
std::uint64_t ForEachPoint(LasSource& in, const std::string& path, const LasHeader& L, bool drop_noise, F&& f) {
  const std::uint64_t per_chunk = std::max<std::uint64_t>(1, kChunkBytes / L.record_length);
  std::vector<unsigned char> buf(std::size_t(std::min(per_chunk, L.count) * L.record_length));
  const bool extended = L.format >= 6;
  std::uint64_t kept = 0;
  for (std::uint64_t done = 0; done < L.count;) {
    const std::uint64_t n = std::min(per_chunk, L.count - done);
    in.ReadAt(path, L.point_offset + done * L.record_length, buf.data(), std::size_t(n * L.record_length),
              "point records");
    for (std::uint64_t i = 0; i < n; ++i) {
      const unsigned char* p = buf.data() + i * L.record_length;
      if (drop_noise) {
        const int cls = extended ? p[16] : p[15] & 31;
        const bool withheld = extended ? (p[15] & 0x04) != 0 : (p[15] & 0x80) != 0;
        if (withheld || cls == 7 || cls == 18) continue;
      }
      f(I32(p) * L.scale[0] + L.offset[0], I32(p + 4) * L.scale[1] + L.offset[1], I32(p + 8) * L.scale[2] + L.offset[2]);
      ++kept;
    }
    done += n;
  }
  return kept;
}

DepthRaster Rasterise(LasSource& in, const std::string& path, const LasRasterOptions& options);

}  // namespace

void LasRasterOptions::Check() const {
  Require(std::isfinite(res_m) && res_m > 0, ErrorCode::kInvalidArgument, "LAS raster: res_m must be > 0");
  Require(std::isfinite(fill_max_gap_m) && fill_max_gap_m >= 0, ErrorCode::kInvalidArgument,
          "LAS raster: fill_max_gap_m must be >= 0");
  Require(max_side > 0, ErrorCode::kInvalidArgument, "LAS raster: max_side must be > 0");
}

DepthRaster RasteriseLas(const std::string& path, const LasRasterOptions& options) {
  options.Check();
  std::error_code ec;
  Require(fs::exists(path, ec), ErrorCode::kIo, path + ": no such file");
  Require(fs::is_regular_file(path, ec), ErrorCode::kIo, path + ": not a regular file");
  if (Lower(fs::path(path).extension().string()) == ".laz") LazError(path);
  const std::uint64_t fsize = fs::file_size(path, ec);
  Require(!ec, ErrorCode::kIo, path + ": cannot read the file size");
  std::ifstream file(path, std::ios::binary);
  Require(file.good(), ErrorCode::kIo, path + ": cannot open for reading");
  LasSource in(file, fsize);
  return Rasterise(in, path, options);
}

DepthRaster RasteriseLasBytes(const std::string& name, const std::uint8_t* data, std::size_t size,
                              const LasRasterOptions& options) {
  options.Check();
  LasSource in(data, size);
  return Rasterise(in, name, options);
}

namespace {

DepthRaster Rasterise(LasSource& in, const std::string& path, const LasRasterOptions& options) {
  const LasHeader L = ReadHeader(in, path);

  // Pass 1: the extent of the kept points (the header bounds are not trusted).
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  const std::uint64_t kept = ForEachPoint(in, path, L, options.drop_noise, [&](double x, double y, double) {
    x0 = std::min(x0, x);
    x1 = std::max(x1, x);
    y0 = std::min(y0, y);
    y1 = std::max(y1, y);
  });
  if (kept == 0)
    Bad(path, "no usable points: all " + std::to_string(L.count) + " are withheld or noise (classes 7, 18)");
  const double r = options.res_m;
  constexpr double kMaxCoord = 1e15;  // cell indices must stay exact in a double and an int64
  if (!(std::fabs(x0 / r) < kMaxCoord && std::fabs(x1 / r) < kMaxCoord && std::fabs(y0 / r) < kMaxCoord &&
        std::fabs(y1 / r) < kMaxCoord))
    Bad(path, "point coordinates are out of range for res_m " + std::to_string(r));
  const std::int64_t c0 = std::int64_t(std::floor(x0 / r)), c1 = std::int64_t(std::floor(x1 / r));
  const std::int64_t r0 = std::int64_t(std::floor(y0 / r)), r1 = std::int64_t(std::floor(y1 / r));
  const std::int64_t w = c1 - c0 + 1, h = r1 - r0 + 1;
  if (w > options.max_side || h > options.max_side)
    Bad(path, "the points span " + std::to_string(x1 - x0) + " x " + std::to_string(y1 - y0) + " m, " +
                  std::to_string(w) + " x " + std::to_string(h) + " cells at res_m " + std::to_string(r) +
                  ", more than max_side " + std::to_string(options.max_side) + " per side; use a coarser res_m");

  // Pass 2: max Z per cell.
  DepthRaster out;
  out.z.create(int(h), int(w));
  out.z.setTo(std::numeric_limits<float>::quiet_NaN());
  ForEachPoint(in, path, L, options.drop_noise, [&](double x, double y, double zv) {
    const std::int64_t c = std::int64_t(std::floor(x / r)) - c0, row = r1 - std::int64_t(std::floor(y / r));
    if (c < 0 || c >= w || row < 0 || row >= h) return;  // cannot happen (same arithmetic as pass 1)
    float& cell = out.z(int(row), int(c));
    const float zf = float(zv);
    if (!std::isfinite(zf)) Bad(path, "a point height is out of range (" + std::to_string(zv) + ")");
    if (!(cell >= zf)) cell = zf;  // NaN compares false: the first point wins
  });
  if (options.fill_max_gap_m > 0) FillDepthHoles(out.z, options.fill_max_gap_m / r);
  out.res_m = r;
  out.geo = {double(c0) * r, r, 0, double(r1 + 1) * r, 0, -r};
  out.has_geo = true;
  out.crs_wkt = L.crs_wkt;
  return out;
}

}  // namespace
}  // namespace mvkp::geo
