#include "mvkp/geo/raster.h"

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp::geo {
namespace {

namespace fs = std::filesystem;

// ---- data and scratch files ------------------------------------------------

// The Montpellier tile: $MVKP_DATA_DIR/aerial/montpellier, else
// <repo>/../shared/data/aerial/montpellier; empty when absent.
std::string Montpellier() {
  const char* env = std::getenv("MVKP_DATA_DIR");
  const fs::path base = env && *env ? fs::path(env) : fs::path(MVKP_SOURCE_DIR) / ".." / "shared" / "data";
  const fs::path dir = base / "aerial" / "montpellier";
  std::error_code ec;
  return fs::exists(dir / "dsm_50cm.tif", ec) ? dir.lexically_normal().string() : std::string();
}

#define REQUIRE_DATA(dir)                                                                              \
  const std::string dir = Montpellier();                                                              \
  if (dir.empty()) GTEST_SKIP() << "aerial test data not found (set MVKP_DATA_DIR or provide " \
                                << MVKP_SOURCE_DIR << "/../shared/data)"

class Scratch : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mvkp_geo_test_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string Write(const std::string& name, const std::vector<std::uint8_t>& bytes) const {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    return p;
  }
  std::string WriteText(const std::string& name, const std::string& text) const {
    return Write(name, std::vector<std::uint8_t>(text.begin(), text.end()));
  }
  fs::path dir_;
};

// Runs f, expecting mvkp::Error with `code` and a message containing `part`.
void ExpectError(const std::function<void()>& f, ErrorCode code, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one containing \"" << part << "\"";
  } catch (const Error& e) {
    EXPECT_EQ(int(e.code()), int(code)) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

int CountNaN(const cv::Mat1f& z) {
  int n = 0;
  for (float v : z) n += std::isnan(v);
  return n;
}

// ---- a small LAS writer ----------------------------------------------------

struct Pt {
  double x, y, z;
  int cls = 2;
  bool withheld = false;
};

struct LasSpec {
  int minor = 2;
  int format = 1;
  int extra_bytes = 0;  // appended to each record
  std::string wkt;      // OGC WKT VLR when non-empty
};

LasSpec Spec(int minor, int format, int extra_bytes = 0) {
  LasSpec s;
  s.minor = minor;
  s.format = format;
  s.extra_bytes = extra_bytes;
  return s;
}

void Put(std::vector<std::uint8_t>& b, std::size_t at, std::uint64_t v, int n) {
  for (int i = 0; i < n; ++i) b[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}
void PutF64(std::vector<std::uint8_t>& b, std::size_t at, double d) {
  std::uint64_t u;
  std::memcpy(&u, &d, 8);
  Put(b, at, u, 8);
}

constexpr double kScale = 0.01, kOffX = 1000, kOffY = 2000;
constexpr int kMinRec[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

std::vector<std::uint8_t> MakeLas(const LasSpec& s, const std::vector<Pt>& pts) {
  const std::size_t header = s.minor >= 4 ? 375 : s.minor == 3 ? 235 : 227;
  const std::size_t vlr = s.wkt.empty() ? 0 : 54 + s.wkt.size() + 1;
  const std::size_t rec = std::size_t(kMinRec[s.format] + s.extra_bytes);
  std::vector<std::uint8_t> b(header + vlr + rec * pts.size(), 0);
  std::memcpy(b.data(), "LASF", 4);
  b[24] = 1;
  b[25] = std::uint8_t(s.minor);
  std::memcpy(b.data() + 26, "mvkp test", 9);
  Put(b, 94, header, 2);
  Put(b, 96, header + vlr, 4);
  Put(b, 100, vlr ? 1 : 0, 4);
  b[104] = std::uint8_t(s.format);
  Put(b, 105, rec, 2);
  Put(b, 107, s.format >= 6 ? 0 : pts.size(), 4);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const Pt& p : pts) {
    const double v[3] = {p.x, p.y, p.z};
    for (int i = 0; i < 3; ++i) lo[i] = std::min(lo[i], v[i]), hi[i] = std::max(hi[i], v[i]);
  }
  for (int i = 0; i < 3; ++i) {
    PutF64(b, 131 + 8 * std::size_t(i), kScale);
    PutF64(b, 179 + 16 * std::size_t(i), hi[i]);
    PutF64(b, 187 + 16 * std::size_t(i), lo[i]);
  }
  PutF64(b, 155, kOffX);
  PutF64(b, 163, kOffY);
  PutF64(b, 171, 0);
  if (s.minor >= 4) Put(b, 247, pts.size(), 8);
  if (vlr) {
    std::memcpy(b.data() + header + 2, "LASF_Projection", 15);
    Put(b, header + 18, 2112, 2);
    Put(b, header + 20, s.wkt.size() + 1, 2);
    std::memcpy(b.data() + header + 54, s.wkt.data(), s.wkt.size());
  }
  std::size_t at = header + vlr;
  for (const Pt& p : pts) {
    Put(b, at, std::uint32_t(std::int32_t(std::lround((p.x - kOffX) / kScale))), 4);
    Put(b, at + 4, std::uint32_t(std::int32_t(std::lround((p.y - kOffY) / kScale))), 4);
    Put(b, at + 8, std::uint32_t(std::int32_t(std::lround(p.z / kScale))), 4);
    if (s.format >= 6) {
      b[at + 14] = 0x11;  // return 1 of 1
      b[at + 15] = p.withheld ? 0x04 : 0;
      b[at + 16] = std::uint8_t(p.cls);
    } else {
      b[at + 14] = 0x09;
      b[at + 15] = std::uint8_t((p.cls & 31) | (p.withheld ? 0x80 : 0));
    }
    at += rec;
  }
  return b;
}

// One point at the centre of each cell (1 m grid from (1000, 2000)) of a
// w x h block, height 10 + col, except the cells skip() says.
std::vector<Pt> Grid(int w, int h, const std::function<bool(int, int)>& skip = {}) {
  std::vector<Pt> pts;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c)
      if (!skip || !skip(c, r)) pts.push_back({kOffX + c + 0.5, kOffY + (h - 1 - r) + 0.5, 10.0 + c});
  return pts;
}

LasRasterOptions Res1() {
  LasRasterOptions o;
  o.res_m = 1.0;
  return o;
}

// ---- GeoTIFF through GDAL --------------------------------------------------

TEST(GeoData, ReadsDsmGeoTiff) {
  REQUIRE_DATA(dir);
  const DepthRaster d = ReadDepthRaster(dir + "/dsm_50cm.tif");
  ASSERT_EQ(d.z.cols, 100);
  ASSERT_EQ(d.z.rows, 100);
  ASSERT_TRUE(d.has_geo);
  EXPECT_NEAR(d.geo[0], 770549.75, 1e-6);
  EXPECT_NEAR(d.geo[3], 6277600.25, 1e-6);
  EXPECT_NEAR(d.geo[1], 0.5, 1e-9);
  EXPECT_NEAR(d.geo[5], -0.5, 1e-9);
  EXPECT_EQ(d.geo[2], 0);
  EXPECT_EQ(d.geo[4], 0);
  EXPECT_NEAR(d.res_m, 0.5, 1e-9);
  EXPECT_NE(d.crs_wkt.find("2154"), std::string::npos) << d.crs_wkt.substr(0, 200);
  int valid = 0;
  for (float v : d.z) {
    if (std::isnan(v)) continue;
    ++valid;
    EXPECT_GT(v, -100.f) << "nodata (-9999) leaked through";
    EXPECT_LT(v, 1000.f);
  }
  EXPECT_GT(valid, 9000);
  EXPECT_LT(valid, 10000);  // the tile has a few nodata (-9999) cells: they are NaN now
}

TEST(GeoData, ReadsNdsmGeoTiff) {
  REQUIRE_DATA(dir);
  const DepthRaster d = ReadDepthRaster(dir + "/ndsm_50cm.tif");
  ASSERT_EQ(d.z.size(), cv::Size(100, 100));
  ASSERT_TRUE(d.has_geo);
  EXPECT_NEAR(d.geo[0], 770549.75, 1e-6);
  EXPECT_NEAR(d.geo[3], 6277600.25, 1e-6);
  EXPECT_NEAR(d.res_m, 0.5, 1e-9);
  float hi = -1e9f;
  for (float v : d.z) {
    if (std::isnan(v)) continue;
    EXPECT_GE(v, -0.5f);
    EXPECT_LE(v, 18.5f);
    hi = std::max(hi, v);
  }
  EXPECT_GT(hi, 15.f);  // README: 0..18.4 m
}

TEST(GeoData, LazAsksToDecompress) {
  REQUIRE_DATA(dir);
  const std::string laz = dir + "/lidar.laz";
  ExpectError([&] { ReadDepthRaster(laz); }, ErrorCode::kBadImage, "decompress first");
  ExpectError([&] { ReadDepthRaster(laz); }, ErrorCode::kBadImage, "pdal translate " + laz);
  ExpectError([&] { RasteriseLas(laz); }, ErrorCode::kBadImage, "LAZ (compressed LAS) is not supported");
}

TEST(GeoData, ReadsOrthoRgb) {
  REQUIRE_DATA(dir);
  const OpticalImage im = ReadOpticalImage(dir + "/ortho_rgb_20cm.tif");
  ASSERT_EQ(im.bgr.cols, 252);
  ASSERT_EQ(im.bgr.rows, 252);
  EXPECT_EQ(im.bgr.type(), CV_8UC3);
  ASSERT_TRUE(im.has_geo);
  EXPECT_NEAR(im.geo[0], 770549.8, 0.1);
  EXPECT_NEAR(im.geo[3], 6277600.2, 0.1);
  EXPECT_NEAR(im.res_m, 0.2, 1e-6);
  cv::Scalar mean, sd;
  cv::meanStdDev(im.bgr, mean, sd);
  EXPECT_GT(sd[0] + sd[1] + sd[2], 10.0);  // a real picture, not a constant
}

TEST_F(Scratch, CompressedBitInALasNamedFile) {
  REQUIRE_DATA(dir);
  const fs::path las = dir_ / "lidar.las";
  fs::copy_file(fs::path(dir) / "lidar.laz", las);
  ExpectError([&] { ReadDepthRaster(las.string()); }, ErrorCode::kBadImage, "decompress first");
  ExpectError([&] { RasteriseLas(las.string()); }, ErrorCode::kBadImage, "lidar_decompressed.las");
}

// ---- LAS -------------------------------------------------------------------

TEST_F(Scratch, LasMaxZPerCell) {
  std::vector<Pt> pts = Grid(10, 8, [](int c, int r) { return c == 5 && r == 4; });
  pts.push_back({kOffX + 2.2, kOffY + 4.7, 50.0});  // cell (2, row 8-1-4 = 3): highest wins
  pts.push_back({kOffX + 2.9, kOffY + 4.1, -3.0});
  const std::string p = Write("a.las", MakeLas(Spec(2, 1), pts));
  const DepthRaster d = RasteriseLas(p, Res1());
  ASSERT_EQ(d.z.size(), cv::Size(10, 8));
  EXPECT_TRUE(d.has_geo);
  EXPECT_DOUBLE_EQ(d.geo[0], 1000.0);
  EXPECT_DOUBLE_EQ(d.geo[3], 2008.0);
  EXPECT_DOUBLE_EQ(d.geo[1], 1.0);
  EXPECT_DOUBLE_EQ(d.geo[5], -1.0);
  EXPECT_DOUBLE_EQ(d.res_m, 1.0);
  EXPECT_NEAR(d.z(3, 2), 50.0f, 1e-4);
  EXPECT_NEAR(d.z(0, 0), 10.0f, 1e-4);
  EXPECT_NEAR(d.z(7, 9), 19.0f, 1e-4);
  // The empty cell is filled from a 4-neighbour (14, 15 or 16).
  EXPECT_GE(d.z(4, 5), 14.0f);
  EXPECT_LE(d.z(4, 5), 16.0f);
  EXPECT_EQ(CountNaN(d.z), 0);

  LasRasterOptions nofill = Res1();
  nofill.fill_max_gap_m = 0;
  EXPECT_TRUE(std::isnan(RasteriseLas(p, nofill).z(4, 5)));

  // The same through ReadDepthRaster, by content (not by extension).
  DepthReadOptions o;
  o.las = Res1();
  const std::string q = Write("points.bin", MakeLas(Spec(2, 1), pts));
  EXPECT_NEAR(ReadDepthRaster(q, o).z(3, 2), 50.0f, 1e-4);
}

TEST_F(Scratch, Las14Format6FiltersNoiseAndReadsWkt) {
  std::vector<Pt> pts = Grid(6, 6);
  Pt noise{kOffX + 1.5, kOffY + 1.5, 999.0};
  noise.cls = 7;
  Pt high{kOffX + 2.5, kOffY + 1.5, 777.0};
  high.cls = 18;
  Pt held{kOffX + 3.5, kOffY + 1.5, 888.0};
  held.withheld = true;
  pts.insert(pts.end(), {noise, high, held});
  LasSpec s = Spec(4, 6);
  s.wkt = "PROJCS[\"RGF93 v1 / Lambert-93\",AUTHORITY[\"EPSG\",\"2154\"]]";
  const std::string p = Write("b.las", MakeLas(s, pts));
  const DepthRaster d = RasteriseLas(p, Res1());
  ASSERT_EQ(d.z.size(), cv::Size(6, 6));
  double hi = 0;
  cv::minMaxLoc(d.z, nullptr, &hi);
  EXPECT_NEAR(hi, 15.0, 1e-4);  // 10 + col 5; noise and withheld dropped
  EXPECT_EQ(d.crs_wkt, s.wkt);

  LasRasterOptions keep = Res1();
  keep.drop_noise = false;
  const DepthRaster k = RasteriseLas(p, keep);
  EXPECT_NEAR(k.z(4, 1), 999.0f, 1e-3);
  EXPECT_NEAR(k.z(4, 2), 777.0f, 1e-3);
  EXPECT_NEAR(k.z(4, 3), 888.0f, 1e-3);
}

TEST_F(Scratch, LasOtherFormatsAndExtraBytes) {
  for (int format : {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10}) {
    for (int extra : {0, 5}) {
      const LasSpec s = Spec(format >= 6 ? 4 : 3, format, extra);
      const std::string p = Write("f.las", MakeLas(s, Grid(4, 3)));
      const DepthRaster d = RasteriseLas(p, Res1());
      ASSERT_EQ(d.z.size(), cv::Size(4, 3)) << "format " << format;
      EXPECT_NEAR(d.z(2, 3), 13.0f, 1e-4) << "format " << format << " extra " << extra;
    }
  }
}

TEST_F(Scratch, LasHoleFillingKeepsLargeGaps) {
  // 30 x 30 m; a 10 x 10 m empty square (wider than 3 m: stays NaN) and a
  // 2-cell gap (filled).
  const auto skip = [](int c, int r) {
    return (c >= 10 && c < 20 && r >= 10 && r < 20) || ((c == 3 || c == 4) && r == 25);
  };
  const std::string p = Write("c.las", MakeLas(Spec(2, 1), Grid(30, 30, skip)));
  const DepthRaster d = RasteriseLas(p, Res1());
  ASSERT_EQ(d.z.size(), cv::Size(30, 30));
  EXPECT_EQ(CountNaN(d.z), 100);
  for (int r = 10; r < 20; ++r)
    for (int c = 10; c < 20; ++c) EXPECT_TRUE(std::isnan(d.z(r, c)));
  EXPECT_FALSE(std::isnan(d.z(25, 3)));
  EXPECT_FALSE(std::isnan(d.z(25, 4)));

  LasRasterOptions wide = Res1();
  wide.fill_max_gap_m = 12;
  EXPECT_EQ(CountNaN(RasteriseLas(p, wide).z), 0);
}

TEST(FillDepthHoles, EdgeCases) {
  cv::Mat1f all(5, 5, std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(FillDepthHoles(all, 10), 0);
  EXPECT_EQ(CountNaN(all), 25);
  cv::Mat1f none(5, 5, 1.f);
  EXPECT_EQ(FillDepthHoles(none, 10), 0);
  cv::Mat1f one(5, 5, 2.f);
  one(2, 2) = std::numeric_limits<float>::quiet_NaN();
  cv::Mat1f copy = one.clone();
  EXPECT_EQ(FillDepthHoles(one, 1), 1);
  EXPECT_EQ(one(2, 2), 2.f);
  EXPECT_EQ(FillDepthHoles(copy, 0.5), 0);
  cv::Mat1f empty;
  EXPECT_EQ(FillDepthHoles(empty, 3), 0);
  ExpectError([&] { FillDepthHoles(one, -1); }, ErrorCode::kInvalidArgument, "max_gap_px");
}

TEST_F(Scratch, LasBadInputs) {
  const std::vector<std::uint8_t> good = MakeLas(Spec(2, 1), Grid(4, 4));
  const auto las = [&](const std::string& name, const std::function<void(std::vector<std::uint8_t>&)>& edit) {
    std::vector<std::uint8_t> b = good;
    edit(b);
    return Write(name, b);
  };
  const auto bad = [&](const std::string& path, const std::string& part) {
    ExpectError([&] { RasteriseLas(path, Res1()); }, ErrorCode::kBadImage, part);
  };
  ExpectError([&] { RasteriseLas((dir_ / "missing.las").string()); }, ErrorCode::kIo, "no such file");
  bad(Write("empty.las", {}), "not a LAS file");
  bad(las("sig.las", [](auto& b) { b[0] = 'X'; }), "no \"LASF\" signature");
  bad(las("short.las", [](auto& b) { b.resize(200); }), "truncated LAS header");
  bad(las("truncated.las", [](auto& b) { b.resize(b.size() - 5); }), "truncated file");
  bad(las("version.las", [](auto& b) { b[24] = 2; }), "unsupported LAS version 2.2");
  bad(las("minor.las", [](auto& b) { b[25] = 9; }), "unsupported LAS version 1.9");
  bad(las("format.las", [](auto& b) { b[104] = 11; }), "unknown point data format 11");
  bad(las("format6.las", [](auto& b) { b[104] = 6; }), "needs LAS 1.4");
  bad(las("reclen.las", [](auto& b) { Put(b, 105, 20, 2); }), "smaller than point format 1 needs (28 bytes)");
  bad(las("hdrsize.las", [](auto& b) { Put(b, 94, 100, 2); }), "header size 100");
  bad(las("offset_in.las", [](auto& b) { Put(b, 96, 10, 4); }), "lies inside the header");
  bad(las("offset_past.las", [](auto& b) { Put(b, 96, 1u << 30, 4); }), "past the end of the file");
  bad(las("count0.las", [](auto& b) { Put(b, 107, 0, 4); }), "declares no points");
  bad(las("count.las", [](auto& b) { Put(b, 107, 1000000000u, 4); }), "declares 1000000000 points");
  bad(las("scale.las", [](auto& b) { PutF64(b, 131, 0.0); }), "X scale/offset");
  bad(las("nanoffset.las", [](auto& b) { PutF64(b, 171, std::nan("")); }), "Z scale/offset");
  bad(las("vlr.las", [](auto& b) { Put(b, 100, 3, 4); }), "runs past the point data offset");
  bad(las("compressed.las", [](auto& b) { b[104] |= 0x80; }), "decompress first");

  // LAS 1.4: 10^12 points declared in a small file, inconsistent counts.
  const std::vector<std::uint8_t> g14 = MakeLas(Spec(4, 6), Grid(4, 4));
  std::vector<std::uint8_t> b = g14;
  Put(b, 247, 1000000000000ull, 8);
  bad(Write("e12.las", b), "declares 1000000000000 points");
  b = g14;
  Put(b, 107, 7, 4);
  bad(Write("counts.las", b), "inconsistent point counts");

  // Every point is noise; points spread too far for the grid; absurd Z.
  std::vector<Pt> noise = Grid(3, 3);
  for (Pt& p : noise) p.cls = 7;
  bad(Write("noise.las", MakeLas(Spec(2, 1), noise)), "no usable points");
  const std::vector<Pt> far = {{kOffX, kOffY, 1}, {kOffX + 20000000 * kScale, kOffY, 2}};
  ExpectError([&] { RasteriseLas(Write("far.las", MakeLas(Spec(2, 1), far))); }, ErrorCode::kBadImage, "coarser res_m");
  bad(las("zscale.las", [](auto& b) { PutF64(b, 147, 1e300); }), "height is out of range");

  // Options.
  LasRasterOptions o;
  o.res_m = 0;
  ExpectError([&] { RasteriseLas(Write("ok.las", good), o); }, ErrorCode::kInvalidArgument, "res_m");
  o = {};
  o.fill_max_gap_m = -1;
  ExpectError([&] { RasteriseLas(Write("ok.las", good), o); }, ErrorCode::kInvalidArgument, "fill_max_gap_m");
}

// From memory: the same raster as from the file, and the same errors, naming
// the given name; every truncation is refused without reading past the end.
TEST_F(Scratch, LasFromBytesMatchesTheFile) {
  LasSpec s = Spec(4, 6);
  s.wkt = "LOCAL_CS[\"x\"]";
  const std::vector<std::uint8_t> good = MakeLas(s, Grid(6, 4));
  const DepthRaster f = RasteriseLas(Write("g.las", good), Res1());
  const DepthRaster m = RasteriseLasBytes("upload", good.data(), good.size(), Res1());
  ASSERT_EQ(m.z.size(), f.z.size());
  EXPECT_EQ(cv::norm(m.z, f.z, cv::NORM_INF), 0.0);
  EXPECT_EQ(m.geo, f.geo);
  EXPECT_EQ(m.crs_wkt, "LOCAL_CS[\"x\"]");
  for (std::size_t n : {std::size_t(0), std::size_t(3), std::size_t(200), good.size() - 1}) {
    const std::vector<std::uint8_t> cut(good.begin(), good.begin() + std::ptrdiff_t(n));
    ExpectError([&] { RasteriseLasBytes("upload", cut.data(), cut.size(), Res1()); }, ErrorCode::kBadImage, "upload: ");
  }
  LasRasterOptions o;
  o.res_m = -1;
  ExpectError([&] { RasteriseLasBytes("upload", good.data(), good.size(), o); }, ErrorCode::kInvalidArgument, "res_m");
}

// Truncations at every length and random byte changes: a result or an
// mvkp::Error, never a crash or another exception.
TEST_F(Scratch, LasFuzzNeverCrashes) {
  LasSpec s = Spec(4, 6);
  s.wkt = "LOCAL_CS[\"x\"]";
  const std::vector<std::uint8_t> good = MakeLas(s, Grid(5, 5));
  LasRasterOptions o = Res1();
  o.max_side = 2000;
  const auto attempt = [&](const std::vector<std::uint8_t>& b) {
    const std::string p = Write("fuzz.las", b);
    try {
      const DepthRaster d = RasteriseLas(p, o);
      EXPECT_FALSE(d.z.empty());
      EXPECT_LE(d.z.cols, o.max_side);
      EXPECT_LE(d.z.rows, o.max_side);
    } catch (const Error&) {
    }
  };
  for (std::size_t n = 0; n < good.size(); ++n) attempt(std::vector<std::uint8_t>(good.begin(), good.begin() + std::ptrdiff_t(n)));
  std::mt19937 rng(8);
  for (int i = 0; i < 1500; ++i) {
    std::vector<std::uint8_t> b = good;
    const int changes = 1 + int(rng() % 4);
    for (int k = 0; k < changes; ++k) {
      // Mostly the header and VLR (where the sizes live), sometimes anywhere.
      const std::size_t at = rng() % 4 ? rng() % 450 : rng() % b.size();
      b[at] = std::uint8_t(rng());
    }
    attempt(b);
  }
}

// ---- GDAL rasters in other formats ----------------------------------------

std::string AsciiGrid(int w, int h, const std::function<double(int, int)>& z) {
  std::string s = "ncols " + std::to_string(w) + "\nnrows " + std::to_string(h) +
                  "\nxllcorner 500000\nyllcorner 6000000\ncellsize 2\nNODATA_value -9999\n";
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) s += std::to_string(z(c, r)) + " ";
    s += "\n";
  }
  return s;
}

TEST_F(Scratch, GdalNodataFlatAndAbsurd) {
  // Nodata becomes NaN; the geotransform is of pixel corners.
  const std::string part = WriteText("part.asc", AsciiGrid(20, 20, [](int c, int r) { return c < 5 ? -9999.0 : c + r; }));
  const DepthRaster d = ReadDepthRaster(part);
  ASSERT_EQ(d.z.size(), cv::Size(20, 20));
  EXPECT_EQ(CountNaN(d.z), 100);
  EXPECT_EQ(d.z(3, 7), 10.0f);
  ASSERT_TRUE(d.has_geo);
  EXPECT_DOUBLE_EQ(d.geo[0], 500000);
  EXPECT_DOUBLE_EQ(d.geo[3], 6000040);
  EXPECT_DOUBLE_EQ(d.res_m, 2);

  const std::string none = WriteText("none.asc", AsciiGrid(20, 20, [](int, int) { return -9999.0; }));
  ExpectError([&] { ReadDepthRaster(none); }, ErrorCode::kBadImage, "every one of the 400 cells is nodata");
  const std::string flat = WriteText("flat.asc", AsciiGrid(20, 20, [](int c, int) { return 42.0 + 0.01 * c; }));
  ExpectError([&] { ReadDepthRaster(flat); }, ErrorCode::kBadImage, "flat depth");
  DepthReadOptions any;
  any.min_relief_m = 0;
  EXPECT_EQ(ReadDepthRaster(flat, any).z.cols, 20);

  // A 10^6 x 10^6 raster is refused before anything is allocated.
  const std::string huge = WriteText("huge.vrt",
                                     "<VRTDataset rasterXSize=\"1000000\" rasterYSize=\"1000000\">\n"
                                     "  <VRTRasterBand dataType=\"Float32\" band=\"1\"/>\n</VRTDataset>\n");
  ExpectError([&] { ReadDepthRaster(huge); }, ErrorCode::kBadImage, "raster size 1000000x1000000 exceeds max_side");

  ExpectError([&] { ReadDepthRaster(WriteText("junk.tif", "this is not a raster\n")); }, ErrorCode::kBadImage,
              "not a depth raster");
  ExpectError([&] { ReadDepthRaster((dir_ / "missing.tif").string()); }, ErrorCode::kIo, "no such file");
  DepthReadOptions bad;
  bad.min_relief_m = -1;
  ExpectError([&] { ReadDepthRaster(part, bad); }, ErrorCode::kInvalidArgument, "min_relief_m");
}

TEST_F(Scratch, OpticalGdalFallback) {
  // A float single-band grid OpenCV cannot read: stretched to 8 bits, gray -> BGR.
  const std::string asc = WriteText("img.asc", AsciiGrid(32, 24, [](int c, int r) { return 100.0 * c + r; }));
  const OpticalImage im = ReadOpticalImage(asc);
  ASSERT_EQ(im.bgr.size(), cv::Size(32, 24));
  EXPECT_EQ(im.bgr.type(), CV_8UC3);
  double lo = 0, hi = 0;
  cv::minMaxLoc(im.bgr.reshape(1), &lo, &hi);
  EXPECT_LE(lo, 5);
  EXPECT_GE(hi, 250);
  EXPECT_TRUE(im.has_geo);
  EXPECT_DOUBLE_EQ(im.res_m, 2);

  ExpectError([&] { ReadOpticalImage(WriteText("junk.xyz", "not an image at all\n")); }, ErrorCode::kBadImage,
              "not an image");
  ExpectError([&] { ReadOpticalImage((dir_ / "missing.png").string()); }, ErrorCode::kIo, "no such file");
  ImageLimits tiny;
  tiny.max_side = 16;
  ExpectError([&] { ReadOpticalImage(asc, tiny); }, ErrorCode::kBadImage, "exceeds the limit");
}

TEST_F(Scratch, OpticalMultiBandThroughGdal) {
  REQUIRE_DATA(dir);
  // A VRT over the GeoTIFF: only GDAL reads it; pixels must equal the direct read.
  std::string vrt = "<VRTDataset rasterXSize=\"252\" rasterYSize=\"252\">\n";
  for (int b = 1; b <= 3; ++b)
    vrt += "<VRTRasterBand dataType=\"Byte\" band=\"" + std::to_string(b) +
           "\"><SimpleSource><SourceFilename relativeToVRT=\"0\">" + dir + "/ortho_rgb_20cm.tif" +
           "</SourceFilename><SourceBand>" + std::to_string(b) + "</SourceBand></SimpleSource></VRTRasterBand>\n";
  vrt += "</VRTDataset>\n";
  const OpticalImage via = ReadOpticalImage(WriteText("ortho.vrt", vrt));
  const OpticalImage direct = ReadOpticalImage(dir + "/ortho_rgb_20cm.tif");
  ASSERT_EQ(via.bgr.size(), cv::Size(252, 252));
  ASSERT_EQ(via.bgr.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(via.bgr, direct.bgr, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace mvkp::geo
