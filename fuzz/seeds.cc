// Writes the generated part of the seed corpus: tiny images, a model in both
// format versions, an FFVA index, .fvecs files and LAS files, each valid one
// with a damaged twin. Usage: mvkp_fuzz_seeds <repo>/fuzz/corpus
// (the text seeds of target_list/ and json/ are written by hand).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "mvkp/core/crc32.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/fvecs.h"
#include "mvkp/model/model.h"

namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<std::uint8_t>;

fs::path root;

void Write(const std::string& target, const std::string& name, const Bytes& b) {
  fs::create_directories(root / target);
  std::ofstream(root / target / name, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}
Bytes Cut(Bytes b, std::size_t n) {
  b.resize(std::min(n, b.size()));
  return b;
}
Bytes Encode(const std::string& ext, const cv::Mat& m, std::vector<int> params = {}) {
  Bytes b;
  cv::imencode(ext, m, b, params);
  return b;
}
void Put(Bytes& b, std::size_t at, std::uint64_t v, int n) {
  for (int i = 0; i < n; ++i) b[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
}
void PutF64(Bytes& b, std::size_t at, double d) {
  std::uint64_t u;
  std::memcpy(&u, &d, 8);
  Put(b, at, u, 8);
}

void Images() {
  cv::Mat gray(16, 16, CV_8UC1), color(8, 12, CV_8UC3);
  for (int y = 0; y < gray.rows; ++y)
    for (int x = 0; x < gray.cols; ++x) gray.at<std::uint8_t>(y, x) = std::uint8_t(x * 16 ^ y * 8);
  cv::randu(color, 0, 255);
  const Bytes png = Encode(".png", gray), jpg = Encode(".jpg", gray, {cv::IMWRITE_JPEG_QUALITY, 50});
  Write("image", "gray16.png", png);
  Write("image", "color.png", Encode(".png", color));
  Write("image", "gray16.jpg", jpg);
  Write("image", "color.jpg", Encode(".jpg", color, {cv::IMWRITE_JPEG_QUALITY, 50}));
  Write("image", "progressive.jpg", Encode(".jpg", color, {cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  Write("image", "gray.pgm", Encode(".pgm", gray));
  Write("image", "color.ppm", Encode(".ppm", color));
  Write("image", "ascii.pgm", Encode(".pgm", gray, {cv::IMWRITE_PXM_BINARY, 0}));
  Write("image", "color.bmp", Encode(".bmp", color));
  Write("image", "truncated.jpg", Cut(jpg, jpg.size() / 2));
  Write("image", "truncated.png", Cut(png, png.size() - 20));
  Bytes huge = png;  // IHDR width and height (big-endian at 16, 20): 100000 x 100000
  for (int at : {16, 20}) huge[std::size_t(at)] = 0, huge[std::size_t(at) + 1] = 1, huge[std::size_t(at) + 2] = 0x86, huge[std::size_t(at) + 3] = 0xA0;
  Write("image", "huge-header.png", huge);
}

mvkp::Model TinyModel() {
  mvkp::Model m;
  m.params.patch_size = 8;
  m.params.dims = 4;
  m.params.orientation_radius = 4;
  m.object_width = 32;
  m.object_height = 24;
  m.locations = {{3.f, 4.f, 5, 0, 1.f}, {10.5f, 7.f, 2, 0, 1.f}};
  m.descriptors = (cv::Mat_<float>(3, 4) << 0.1f, -0.2f, 0.3f, 0.f, 1.f, 2.f, 3.f, 4.f, -1.f, 0.5f, 0.25f, 8.f);
  m.labels = {0, 1, 1};
  return m;
}

void Models() {
  const Bytes v2 = mvkp::SerializeModel(TinyModel());
  Write("model", "tiny-v2.mvkp", v2);
  // Version 1: no envelope fields (17 bytes after train_ms) and no level and
  // scale per location (5 bytes each); see model.cc.
  const std::size_t hdr = 20, params_v1 = 4 + 4 + 4 + 1 + 4 + 4 + 4 + 4 + 4 + 4 + 4 + 4 + 8 + 4 + 4 + 8;
  Bytes p(v2.begin() + hdr, v2.end() - 4);
  Bytes q(p.begin(), p.begin() + std::ptrdiff_t(params_v1));
  std::size_t at = params_v1 + 17;
  q.insert(q.end(), p.begin() + std::ptrdiff_t(at), p.begin() + std::ptrdiff_t(at + 12));  // object size, count
  std::uint32_t nl;
  std::memcpy(&nl, p.data() + at + 8, 4);
  at += 12;
  for (std::uint32_t i = 0; i < nl; ++i, at += 17) q.insert(q.end(), p.begin() + std::ptrdiff_t(at), p.begin() + std::ptrdiff_t(at + 12));
  q.insert(q.end(), p.begin() + std::ptrdiff_t(at), p.end());
  Bytes v1(v2.begin(), v2.begin() + 20);
  Put(v1, 8, 1, 4);
  Put(v1, 12, q.size(), 8);
  v1.insert(v1.end(), q.begin(), q.end());
  const std::uint32_t crc = mvkp::Crc32(q.data(), q.size());
  for (int i = 0; i < 4; ++i) v1.push_back(std::uint8_t(crc >> (8 * i)));
  Write("model", "tiny-v1.mvkp", v1);
  Write("model", "truncated.mvkp", Cut(v2, v2.size() - 9));
  Bytes flipped = v2;
  flipped[40] ^= 0x10;
  Write("model", "bad-crc.mvkp", flipped);
}

void Indexes() {
  constexpr int n = 40, dim = 3;
  std::vector<float> v(n * dim);
  std::vector<std::int32_t> labels(n);
  for (int i = 0; i < n; ++i) {
    labels[std::size_t(i)] = i % 5;
    for (int j = 0; j < dim; ++j) v[std::size_t(i * dim + j)] = float(std::sin(i * 1.7 + j) * 10);
  }
  mvkp::FfvaOptions o;
  o.leaf_size = 32;
  auto index = mvkp::MakeFfvaIndex(o);
  index->Build(v.data(), n, dim, labels.data());
  const fs::path dir = root / "index";
  fs::create_directories(dir);
  mvkp::SaveIndex(*index, (dir / "ffva-40x3.idx").string());
  mvkp::WriteFvecs((dir / "five-3d.fvecs").string(), v.data(), 5, dim);
  mvkp::WriteFvecs((dir / "forty-3d.fvecs").string(), v.data(), n, dim);
  std::ifstream in(dir / "five-3d.fvecs", std::ios::binary);
  Bytes f((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Write("index", "truncated.fvecs", Cut(f, f.size() - 3));
  Bytes d = f;
  Put(d, 16, 7, 4);  // second record's dimension
  Write("index", "mixed-dims.fvecs", d);
}

// LAS 1.2 point format 1, or 1.4 format 6 with an OGC WKT VLR; a 3 x 3 grid.
Bytes Las(int minor, int format) {
  const std::size_t header = minor >= 4 ? 375 : 227, rec = format >= 6 ? 30 : 28;
  const std::string wkt = minor >= 4 ? "LOCAL_CS[\"x\"]" : "";
  const std::size_t vlr = wkt.empty() ? 0 : 54 + wkt.size() + 1;
  const int npts = 9;
  Bytes b(header + vlr + rec * npts, 0);
  std::memcpy(b.data(), "LASF", 4);
  b[24] = 1;
  b[25] = std::uint8_t(minor);
  Put(b, 94, header, 2);
  Put(b, 96, header + vlr, 4);
  Put(b, 100, vlr ? 1 : 0, 4);
  b[104] = std::uint8_t(format);
  Put(b, 105, rec, 2);
  Put(b, 107, format >= 6 ? 0 : npts, 4);
  for (int i = 0; i < 3; ++i) PutF64(b, 131 + 8 * std::size_t(i), 0.01);
  PutF64(b, 155, 1000);
  PutF64(b, 163, 2000);
  if (minor >= 4) Put(b, 247, npts, 8);
  if (vlr) {
    std::memcpy(b.data() + header + 2, "LASF_Projection", 15);
    Put(b, header + 18, 2112, 2);
    Put(b, header + 20, wkt.size() + 1, 2);
    std::memcpy(b.data() + header + 54, wkt.data(), wkt.size());
  }
  for (int i = 0; i < npts; ++i) {
    const std::size_t at = header + vlr + rec * std::size_t(i);
    Put(b, at, std::uint32_t((i % 3) * 100 + 50), 4);
    Put(b, at + 4, std::uint32_t((i / 3) * 100 + 50), 4);
    Put(b, at + 8, std::uint32_t(1000 + 37 * i), 4);
    if (format >= 6) b[at + 16] = std::uint8_t(i == 4 ? 7 : 2);
    else b[at + 15] = std::uint8_t(i == 4 ? 7 : 2);
  }
  return b;
}

void LasFiles() {
  const Bytes a = Las(2, 1), b = Las(4, 6);
  Write("las", "grid-1.2-f1.las", a);
  Write("las", "grid-1.4-f6-wkt.las", b);
  Write("las", "truncated.las", Cut(a, a.size() - 5));
  Bytes laz = a;
  laz[104] |= 0x80;
  Write("las", "compressed-bit.las", laz);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <repo>/fuzz/corpus\n", argv[0]);
    return 2;
  }
  root = argv[1];
  Images();
  Models();
  Indexes();
  LasFiles();
  return 0;
}
