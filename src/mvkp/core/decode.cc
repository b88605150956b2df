#include "mvkp/core/internal/decode.h"

#include <csetjmp>
#include <cstdio>
#include <cctype>
#include <vector>

#include <jpeglib.h>
#include <png.h>
#include <opencv2/imgproc.hpp>

namespace mvkp::internal {
namespace {

struct JpegErr {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  int warnings = 0;
  char message[JMSG_LENGTH_MAX] = {0};
};

void JpegErrorExit(j_common_ptr cinfo) {
  auto* e = reinterpret_cast<JpegErr*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, e->message);
  std::longjmp(e->jump, 1);
}

void JpegEmit(j_common_ptr cinfo, int level) {
  auto* e = reinterpret_cast<JpegErr*>(cinfo->err);
  if (level < 0) {  // a warning: corrupt or missing data
    if (e->warnings++ == 0) (*cinfo->err->format_message)(cinfo, e->message);
  }
}

}  // namespace

bool DecodeJpeg(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error,
                int reduce) {
  jpeg_decompress_struct cinfo;
  JpegErr err;
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = JpegErrorExit;
  err.mgr.emit_message = JpegEmit;
  cv::Mat img;  // declared before setjmp so that longjmp does not skip its destructor
  if (setjmp(err.jump)) {
    jpeg_destroy_decompress(&cinfo);
    error = std::string("corrupt JPEG data: ") + err.message;
    return false;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  // libjpeg converts CMYK and YCCK only to CMYK; the conversion to BGR is ours.
  const bool cmyk = cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK;
  cinfo.out_color_space = cmyk ? JCS_CMYK : gray ? JCS_GRAYSCALE : JCS_EXT_BGR;
  cinfo.scale_num = 1;
  cinfo.scale_denom = static_cast<unsigned int>(reduce == 2 || reduce == 4 || reduce == 8 ? reduce : 1);
  jpeg_start_decompress(&cinfo);
  img.create(int(cinfo.output_height), int(cinfo.output_width), cmyk ? CV_8UC4 : gray ? CV_8UC1 : CV_8UC3);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = img.ptr<std::uint8_t>(int(cinfo.output_scanline));
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  // Adobe's CMYK JPEGs (the usual kind) store the inks inverted.
  const bool inverted = cinfo.saw_Adobe_marker;
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  if (err.warnings > 0) {
    error = std::string("corrupt or truncated JPEG data: ") + err.message;
    return false;
  }
  if (cmyk) {
    // Naive CMYK -> RGB without a colour profile: R = (1-C)(1-K), and so on.
    cv::Mat bgr(img.rows, img.cols, CV_8UC3);
    for (int y = 0; y < img.rows; ++y) {
      const std::uint8_t* s = img.ptr<std::uint8_t>(y);
      std::uint8_t* d = bgr.ptr<std::uint8_t>(y);
      for (int x = 0; x < img.cols; ++x, s += 4, d += 3) {
        const int c = inverted ? s[0] : 255 - s[0], m = inverted ? s[1] : 255 - s[1];
        const int yy = inverted ? s[2] : 255 - s[2], k = inverted ? s[3] : 255 - s[3];
        d[0] = std::uint8_t((yy * k + 127) / 255);
        d[1] = std::uint8_t((m * k + 127) / 255);
        d[2] = std::uint8_t((c * k + 127) / 255);
      }
    }
    if (gray) cv::cvtColor(bgr, img, cv::COLOR_BGR2GRAY);
    else img = bgr;
  }
  out = img;
  return true;
}

bool DecodePng(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error) {
  // libpng's simplified API reports errors in image.message and prints nothing.
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, data, size)) {
    error = std::string("corrupt PNG: ") + image.message;
    return false;
  }
  image.format = PNG_FORMAT_BGR;
  image.flags |= PNG_IMAGE_FLAG_16BIT_sRGB;
  cv::Mat bgr(int(image.height), int(image.width), CV_8UC3);
  if (!png_image_finish_read(&image, nullptr, bgr.data, png_int_32(bgr.step), nullptr)) {
    error = std::string("corrupt PNG data: ") + image.message;
    png_image_free(&image);
    return false;
  }
  if (gray) cv::cvtColor(bgr, out, cv::COLOR_BGR2GRAY);
  else out = bgr;
  return true;
}

bool DecodePnm(const std::uint8_t* d, std::size_t n, bool gray, cv::Mat& out, std::string& error) {
  if (n < 3 || d[0] != 'P') return false;
  const char kind = char(d[1]);
  if (kind != '2' && kind != '3' && kind != '5' && kind != '6') return false;
  std::size_t i = 2;
  auto skip = [&] {
    while (i < n && (std::isspace(d[i]) || d[i] == '#')) {
      if (d[i] == '#') while (i < n && d[i] != '\n') ++i;
      else ++i;
    }
  };
  auto number = [&](long& v) {
    skip();
    if (i >= n || !std::isdigit(d[i])) return false;
    v = 0;
    while (i < n && std::isdigit(d[i])) {
      v = v * 10 + (d[i] - '0');
      if (v > 1'000'000'000L) return false;
      ++i;
    }
    return true;
  };
  long w, h, maxval;
  if (!number(w) || !number(h) || !number(maxval) || w <= 0 || h <= 0 || maxval <= 0 || maxval > 65535) {
    error = "malformed PNM header";
    return false;
  }
  const int ch = (kind == '3' || kind == '6') ? 3 : 1;
  const std::size_t count = std::size_t(w) * std::size_t(h) * ch;
  std::vector<std::uint16_t> v(count);
  if (kind == '5' || kind == '6') {
    ++i;  // the single whitespace after maxval
    const int bytes = maxval > 255 ? 2 : 1;
    if (n < i + count * bytes) {
      error = "truncated file (pixel data shorter than the header declares)";
      return false;
    }
    for (std::size_t k = 0; k < count; ++k)
      v[k] = bytes == 1 ? d[i + k] : std::uint16_t((d[i + 2 * k] << 8) | d[i + 2 * k + 1]);
  } else {
    for (std::size_t k = 0; k < count; ++k) {
      long x;
      if (!number(x)) {
        error = "truncated or malformed ASCII PNM data";
        return false;
      }
      v[k] = std::uint16_t(std::min(x, maxval));
    }
  }
  cv::Mat img(int(h), int(w), ch == 3 ? CV_8UC3 : CV_8UC1);
  std::uint8_t* p = img.data;
  for (std::size_t k = 0; k < count; ++k) p[k] = std::uint8_t((v[k] * 255 + maxval / 2) / maxval);
  if (ch == 3) cv::cvtColor(img, img, cv::COLOR_RGB2BGR);
  if (gray && ch == 3) cv::cvtColor(img, out, cv::COLOR_BGR2GRAY);
  else if (!gray && ch == 1) cv::cvtColor(img, out, cv::COLOR_GRAY2BGR);
  else out = img;
  return true;
}

}  // namespace mvkp::internal
