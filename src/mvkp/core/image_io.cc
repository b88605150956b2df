#include "mvkp/core/image_io.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/internal/decode.h"

namespace mvkp {
namespace {

[[noreturn]] void Bad(const std::string& name, const std::string& what) {
  throw Error(ErrorCode::kBadImage, name + ": " + what);
}

std::uint32_t Be32(const std::uint8_t* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}
std::uint16_t Be16(const std::uint8_t* p) { return std::uint16_t((p[0] << 8) | p[1]); }
std::int32_t Le32(const std::uint8_t* p) {
  return std::int32_t(std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) |
                      (std::uint32_t(p[3]) << 24));
}

// PNM header: magic, width, height[, maxval], with '#' comments between tokens.
ImageHeader ReadPnm(const std::string& name, const std::uint8_t* d, std::size_t n) {
  ImageHeader h;
  h.format = "pnm";
  const char kind = char(d[1]);
  const int ntok = (kind == '1' || kind == '4') ? 2 : 3;
  std::size_t i = 2;
  long tok[3] = {0, 0, 0};
  for (int t = 0; t < ntok; ++t) {
    while (i < n && (std::isspace(d[i]) || d[i] == '#')) {
      if (d[i] == '#') while (i < n && d[i] != '\n') ++i;
      else ++i;
    }
    if (i >= n || !std::isdigit(d[i])) Bad(name, "truncated or malformed PNM header");
    long v = 0;
    while (i < n && std::isdigit(d[i])) {
      v = v * 10 + (d[i] - '0');
      if (v > 1'000'000'000L) Bad(name, "PNM header declares an absurd size");
      ++i;
    }
    tok[t] = v;
  }
  h.width = int(tok[0]);
  h.height = int(tok[1]);
  if (kind == '5' || kind == '6') {  // binary: the pixel data must be complete
    const long maxval = tok[2];
    if (maxval <= 0 || maxval > 65535) Bad(name, "PNM header has an invalid maxval");
    const std::size_t bytes = std::size_t(h.width) * std::size_t(h.height) * (kind == '6' ? 3 : 1) *
                              (maxval > 255 ? 2 : 1);
    if (n < i + 1 + bytes) {
      h.complete = false;
      h.incomplete = "truncated file (pixel data shorter than the header declares)";
    }
  }
  return h;
}

ImageHeader ReadJpeg(const std::string& name, const std::uint8_t* d, std::size_t n) {
  ImageHeader h;
  h.format = "jpeg";
  std::size_t i = 2;
  while (i + 4 <= n) {
    if (d[i] != 0xFF) Bad(name, "malformed JPEG marker stream");
    const std::uint8_t m = d[i + 1];
    if (m == 0xFF) { ++i; continue; }
    if (m == 0xD8 || (m >= 0xD0 && m <= 0xD7) || m == 0x01) { i += 2; continue; }
    const std::size_t len = Be16(d + i + 2);
    const bool sof = (m >= 0xC0 && m <= 0xCF) && m != 0xC4 && m != 0xC8 && m != 0xCC;
    if (sof) {
      if (i + 9 > n) break;
      h.height = Be16(d + i + 5);
      h.width = Be16(d + i + 7);
      break;
    }
    if (m == 0xDA || m == 0xD9) break;
    i += 2 + len;
  }
  if (h.width == 0 || h.height == 0) Bad(name, "truncated or malformed JPEG header (no frame size)");
  // Entropy-coded data stuffs 0xFF with 0x00, so 0xFFD9 near the end is the EOI marker.
  const std::size_t tail = std::min<std::size_t>(n, 4096);
  bool eoi = false;
  for (std::size_t k = n - tail; k + 1 < n; ++k)
    if (d[k] == 0xFF && d[k + 1] == 0xD9) eoi = true;
  if (!eoi) {
    h.complete = false;
    h.incomplete = "truncated JPEG (no end-of-image marker)";
  }
  return h;
}

ImageHeader ReadPng(const std::string& name, const std::uint8_t* d, std::size_t n) {
  ImageHeader h;
  h.format = "png";
  if (n < 33 || std::memcmp(d + 12, "IHDR", 4) != 0) Bad(name, "truncated or malformed PNG header");
  const std::uint32_t w = Be32(d + 16), hh = Be32(d + 20);
  if (w > 0x7fffffffu || hh > 0x7fffffffu) Bad(name, "PNG header declares an absurd size");
  h.width = int(w);
  h.height = int(hh);
  bool iend = false;
  const std::size_t tail = std::min<std::size_t>(n, 64);
  for (std::size_t k = n - tail; k + 4 <= n; ++k)
    if (std::memcmp(d + k, "IEND", 4) == 0) iend = true;
  if (!iend) {
    h.complete = false;
    h.incomplete = "truncated PNG (no IEND chunk)";
  }
  return h;
}

// WebP's canvas size, from its first chunk (lossy VP8, lossless VP8L or the
// extended VP8X), so that the pixel limit holds before decoding.
ImageHeader ReadWebp(const std::uint8_t* d, std::size_t n) {
  ImageHeader h;
  h.format = "webp";
  if (n >= 30 && std::memcmp(d + 12, "VP8 ", 4) == 0 && d[23] == 0x9d && d[24] == 0x01 && d[25] == 0x2a) {
    h.width = (d[26] | (d[27] << 8)) & 0x3fff;
    h.height = (d[28] | (d[29] << 8)) & 0x3fff;
  } else if (n >= 25 && std::memcmp(d + 12, "VP8L", 4) == 0 && d[20] == 0x2f) {
    const std::uint32_t b = std::uint32_t(d[21]) | std::uint32_t(d[22]) << 8 | std::uint32_t(d[23]) << 16 |
                            std::uint32_t(d[24]) << 24;
    h.width = int(b & 0x3fff) + 1;
    h.height = int((b >> 14) & 0x3fff) + 1;
  } else if (n >= 30 && std::memcmp(d + 12, "VP8X", 4) == 0) {
    h.width = int(d[24] | (d[25] << 8) | (d[26] << 16)) + 1;
    h.height = int(d[27] | (d[28] << 8) | (d[29] << 16)) + 1;
  }
  return h;
}

void CheckDims(const std::string& name, long long w, long long h, const ImageLimits& lim) {
  if (w <= 0 || h <= 0) Bad(name, "empty image (0 pixels)");
  if (w > lim.max_side || h > lim.max_side || w * h > lim.max_pixels)
    Bad(name, "image size " + std::to_string(w) + "x" + std::to_string(h) + " exceeds the limit (" +
                  std::to_string(lim.max_side) + " px per side, " + std::to_string(lim.max_pixels) +
                  " pixels)");
  if (w < lim.min_side || h < lim.min_side)
    Bad(name, "image is " + std::to_string(w) + "x" + std::to_string(h) + ", smaller than the minimum " +
                  std::to_string(lim.min_side) + "x" + std::to_string(lim.min_side));
}

cv::Mat Decode(const std::string& path, const std::vector<std::uint8_t>& buf, int flags, const ImageLimits& lim);

cv::Mat Load(const std::string& path, int flags, const ImageLimits& lim) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(ErrorCode::kIo, path + ": no such file");
  if (std::filesystem::is_directory(path, ec)) throw Error(ErrorCode::kIo, path + ": is a directory, not an image");
  const auto fsize = std::filesystem::file_size(path, ec);
  if (ec) throw Error(ErrorCode::kIo, path + ": cannot read file size: " + ec.message());
  if (fsize == 0) Bad(path, "empty file");
  if (std::int64_t(fsize) > lim.max_file_bytes) Bad(path, "file is larger than the " + std::to_string(lim.max_file_bytes) + "-byte limit");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorCode::kIo, path + ": cannot open for reading");
  std::vector<std::uint8_t> buf(fsize);
  in.read(reinterpret_cast<char*>(buf.data()), std::streamsize(fsize));
  if (!in) throw Error(ErrorCode::kIo, path + ": read error");
  return Decode(path, buf, flags, lim);
}

cv::Mat Decode(const std::string& path, const std::vector<std::uint8_t>& buf, int flags, const ImageLimits& lim) {
  if (buf.empty()) Bad(path, "empty file");
  if (std::int64_t(buf.size()) > lim.max_file_bytes) Bad(path, "file is larger than the " + std::to_string(lim.max_file_bytes) + "-byte limit");
  const ImageHeader h = ReadImageHeader(path, buf.data(), buf.size());
  if (h.format == "unknown") Bad(path, "not an image (unrecognised file format)");
  if (h.format == "gif") Bad(path, "GIF images are not supported; convert it to PNG or JPEG");
  if (h.format == "heif")
    Bad(path, "HEIC/HEIF images are not supported; convert it to JPEG (or set the phone's camera to 'Most Compatible')");
  if (h.format == "avif") Bad(path, "AVIF images are not supported; convert it to JPEG or PNG");
  if (h.width || h.height) CheckDims(path, h.width, h.height, lim);
  if (!h.complete) Bad(path, h.incomplete);
  cv::Mat img;
  std::string err;
  const bool gray = flags == cv::IMREAD_GRAYSCALE;
  bool handled = true, ok = false;
  if (h.format == "jpeg") ok = internal::DecodeJpeg(buf.data(), buf.size(), gray, img, err);
  else if (h.format == "png") ok = internal::DecodePng(buf.data(), buf.size(), gray, img, err);
  else if (h.format == "pnm") {
    ok = internal::DecodePnm(buf.data(), buf.size(), gray, img, err);
    handled = ok || !err.empty();
  } else handled = false;
  if (handled && !ok) Bad(path, err);
  if (!handled) {
    try {
      img = cv::imdecode(buf, flags);
    } catch (const cv::Exception& e) {
      Bad(path, std::string("cannot decode image: ") + e.err);
    }
    if (img.empty()) Bad(path, "cannot decode image (corrupt or truncated " + h.format + " data)");
  }
  CheckDims(path, img.cols, img.rows, lim);
  if (img.depth() != CV_8U) {
    cv::Mat tmp;
    img.convertTo(tmp, CV_8U, img.depth() == CV_16U ? 1.0 / 257.0 : 1.0);
    img = tmp;
  }
  return img;
}

}  // namespace

ImageHeader ReadImageHeader(const std::string& name, const std::uint8_t* d, std::size_t n) {
  if (n >= 8 && std::memcmp(d, "\x89PNG\r\n\x1a\n", 8) == 0) return ReadPng(name, d, n);
  if (n >= 3 && d[0] == 0xFF && d[1] == 0xD8 && d[2] == 0xFF) return ReadJpeg(name, d, n);
  if (n >= 3 && d[0] == 'P' && d[1] >= '1' && d[1] <= '6' && std::isspace(d[2])) return ReadPnm(name, d, n);
  if (n >= 26 && d[0] == 'B' && d[1] == 'M') {
    const long long w = Le32(d + 18), h = Le32(d + 22);
    ImageHeader hd;
    hd.format = "bmp";
    hd.width = int(std::min<long long>(std::llabs(w), 1LL << 30));
    hd.height = int(std::min<long long>(std::llabs(h), 1LL << 30));
    return hd;
  }
  ImageHeader other;
  if (n >= 4 && (std::memcmp(d, "II*\0", 4) == 0 || std::memcmp(d, "MM\0*", 4) == 0)) other.format = "tiff";
  else if (n >= 12 && std::memcmp(d, "RIFF", 4) == 0 && std::memcmp(d + 8, "WEBP", 4) == 0) return ReadWebp(d, n);
  else if (n >= 10 && (std::memcmp(d, "GIF87a", 6) == 0 || std::memcmp(d, "GIF89a", 6) == 0)) {
    other.format = "gif";
    other.width = int(d[6] | (d[7] << 8));
    other.height = int(d[8] | (d[9] << 8));
  } else if (n >= 12 && std::memcmp(d + 4, "ftyp", 4) == 0) {
    const std::string brand(reinterpret_cast<const char*>(d + 8), 4);
    if (brand == "avif" || brand == "avis") other.format = "avif";
    else if (brand == "heic" || brand == "heix" || brand == "hevc" || brand == "hevx" || brand == "heim" ||
             brand == "heis" || brand == "mif1" || brand == "msf1")
      other.format = "heif";
    else other.format = "unknown";  // e.g. an MP4 video
  } else other.format = "unknown";
  return other;
}

cv::Mat LoadImageGray(const std::string& path, const ImageLimits& limits) {
  return Load(path, cv::IMREAD_GRAYSCALE, limits);
}

cv::Mat LoadImageColor(const std::string& path, const ImageLimits& limits) {
  return Load(path, cv::IMREAD_COLOR, limits);
}

cv::Mat DecodeImageGray(const std::string& name, const std::vector<std::uint8_t>& bytes, const ImageLimits& limits) {
  return Decode(name, bytes, cv::IMREAD_GRAYSCALE, limits);
}

ReducedImage DecodeImageGrayReduced(const std::string& name, const std::vector<std::uint8_t>& bytes, int min_side,
                                    const ImageLimits& limits) {
  ReducedImage r;
  const ImageHeader h = bytes.empty() ? ImageHeader{} : ReadImageHeader(name, bytes.data(), bytes.size());
  const int longer = std::max(h.width, h.height);
  if (h.format == "jpeg" && min_side > 0 && h.complete)
    while (r.reduce < 8 && longer / (2 * r.reduce) >= min_side) r.reduce *= 2;
  if (r.reduce == 1) {
    r.gray = Decode(name, bytes, cv::IMREAD_GRAYSCALE, limits);
    r.full = r.gray.size();
    return r;
  }
  if (std::int64_t(bytes.size()) > limits.max_file_bytes)
    Bad(name, "file is larger than the " + std::to_string(limits.max_file_bytes) + "-byte limit");
  CheckDims(name, h.width, h.height, limits);
  std::string err;
  if (!internal::DecodeJpeg(bytes.data(), bytes.size(), true, r.gray, err, r.reduce)) Bad(name, err);
  r.full = cv::Size(h.width, h.height);
  return r;
}

void CheckImage(const cv::Mat& image, const std::string& name, const ImageLimits& limits) {
  if (image.empty()) Bad(name, "empty image (0 pixels)");
  if (image.depth() != CV_8U) Bad(name, "expected 8-bit pixels");
  CheckDims(name, image.cols, image.rows, limits);
}

void SaveImage(const std::string& path, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, image);
  } catch (const cv::Exception& e) {
    throw Error(ErrorCode::kIo, path + ": cannot write image: " + e.err);
  }
  if (!ok) throw Error(ErrorCode::kIo, path + ": cannot write image (unknown extension or unwritable path)");
}

}  // namespace mvkp
