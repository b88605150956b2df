#include "mvkp/core/image_io.h"

#include <filesystem>
#include <fstream>
#include <vector>

#include <cstdio>

#include <gtest/gtest.h>
#include <jpeglib.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;

class ImageIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mvkp_io_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    cv::Mat img(64, 80, CV_8UC3);
    cv::randu(img, 0, 255);
    png_ = (dir_ / "a.png").string();
    jpg_ = (dir_ / "a.jpg").string();
    cv::imwrite(png_, img);
    cv::imwrite(jpg_, img);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::vector<char>& bytes) {
    const auto p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
    return p;
  }
  std::vector<char> Read(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  // Expects LoadImageGray(path) to throw a message naming the file and containing `what`.
  void ExpectError(const std::string& path, const std::string& what) {
    try {
      LoadImageGray(path);
      FAIL() << "no error for " << path;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }
  fs::path dir_;
  std::string png_, jpg_;
};

TEST_F(ImageIo, LoadsGoodImages) {
  EXPECT_EQ(LoadImageGray(png_).size(), cv::Size(80, 64));
  EXPECT_EQ(LoadImageGray(jpg_).type(), CV_8UC1);
  EXPECT_EQ(LoadImageColor(png_).type(), CV_8UC3);
}

TEST_F(ImageIo, MissingFile) { ExpectError((dir_ / "nope.png").string(), "no such file"); }

TEST_F(ImageIo, EmptyAndNonImageFiles) {
  ExpectError(Write("empty.png", {}), "empty file");
  ExpectError(Write("text.png", {'h', 'e', 'l', 'l', 'o', '\n', 'w', 'o', 'r', 'l', 'd'}), "not an image");
}

TEST_F(ImageIo, TruncatedFiles) {
  auto png = Read(png_);
  png.resize(png.size() / 2);
  ExpectError(Write("trunc.png", png), "truncated");
  auto jpg = Read(jpg_);
  jpg.resize(jpg.size() / 2);
  ExpectError(Write("trunc.jpg", jpg), "truncated");
  std::vector<char> pgm = {'P', '5', '\n', '6', '4', ' ', '6', '4', '\n', '2', '5', '5', '\n'};
  pgm.resize(pgm.size() + 100, 'x');
  ExpectError(Write("trunc.pgm", pgm), "truncated");
}

TEST_F(ImageIo, TinyImage) {
  cv::Mat one(1, 1, CV_8UC1, cv::Scalar(7));
  const auto p = (dir_ / "one.png").string();
  cv::imwrite(p, one);
  ExpectError(p, "smaller than the minimum");
}

TEST_F(ImageIo, AbsurdDeclaredSize) {
  // A PNG header declaring 100000 x 100000: refused before any decode or allocation.
  auto png = Read(png_);
  auto put = [&](int off, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) png[off + i] = char((v >> (24 - 8 * i)) & 0xFF);
  };
  put(16, 100000);
  put(20, 100000);
  ExpectError(Write("huge.png", png), "exceeds the limit");
  std::vector<char> pgm = {'P', '5', ' ', '1', '0', '0', '0', '0', '0', ' ', '1', '0', '0', '0', '0', '0', ' ', '2', '5', '5', '\n', 0};
  ExpectError(Write("huge.pgm", pgm), "exceeds the limit");
}

TEST_F(ImageIo, DirectoryIsNotAnImage) { ExpectError(dir_.string(), "directory"); }

// A CMYK JPEG as Adobe's tools write it (inverted inks, Adobe marker), made
// with libjpeg from a BGR image: C = 255 - R etc. with K = 0, so the decoder's
// naive conversion must give the image back up to JPEG loss.
std::vector<std::uint8_t> EncodeAdobeCmyk(const cv::Mat& bgr) {
  jpeg_compress_struct c;
  jpeg_error_mgr err;
  c.err = jpeg_std_error(&err);
  jpeg_create_compress(&c);
  unsigned char* buf = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&c, &buf, &size);
  c.image_width = JDIMENSION(bgr.cols);
  c.image_height = JDIMENSION(bgr.rows);
  c.input_components = 4;
  c.in_color_space = JCS_CMYK;
  jpeg_set_defaults(&c);
  jpeg_set_colorspace(&c, JCS_YCCK);
  c.write_Adobe_marker = TRUE;
  jpeg_set_quality(&c, 95, TRUE);
  jpeg_start_compress(&c, TRUE);
  std::vector<std::uint8_t> row(std::size_t(bgr.cols) * 4);
  while (c.next_scanline < c.image_height) {
    const std::uint8_t* s = bgr.ptr<std::uint8_t>(int(c.next_scanline));
    for (int x = 0; x < bgr.cols; ++x) {
      // Inverted (Adobe) CMYK stores 255 - ink: with K = 0 that is R, G, B and 255.
      row[4 * x + 0] = s[3 * x + 2];
      row[4 * x + 1] = s[3 * x + 1];
      row[4 * x + 2] = s[3 * x + 0];
      row[4 * x + 3] = 255;
    }
    JSAMPROW r = row.data();
    jpeg_write_scanlines(&c, &r, 1);
  }
  jpeg_finish_compress(&c);
  jpeg_destroy_compress(&c);
  std::vector<std::uint8_t> out(buf, buf + size);
  std::free(buf);
  return out;
}

cv::Mat Smooth(int w, int h) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) img.at<cv::Vec3b>(y, x) = cv::Vec3b(std::uint8_t(x * 255 / w), std::uint8_t(y * 255 / h), 128);
  cv::circle(img, {w / 2, h / 2}, std::min(w, h) / 4, cv::Scalar(20, 200, 90), -1);
  return img;
}

TEST_F(ImageIo, CmykJpegDecodesLikeItsRgbSource) {
  const cv::Mat bgr = Smooth(120, 90);
  const auto bytes = EncodeAdobeCmyk(bgr);
  const cv::Mat gray = DecodeImageGray("cmyk.jpg", bytes);
  cv::Mat want;
  cv::cvtColor(bgr, want, cv::COLOR_BGR2GRAY);
  ASSERT_EQ(gray.size(), want.size());
  cv::Mat diff;
  cv::absdiff(gray, want, diff);
  EXPECT_LT(cv::mean(diff)[0], 3.0);
  const auto p = Write("cmyk.jpg", std::vector<char>(bytes.begin(), bytes.end()));
  const cv::Mat color = LoadImageColor(p);
  ASSERT_EQ(color.type(), CV_8UC3);
  cv::absdiff(color, bgr, diff);
  EXPECT_LT(cv::mean(diff)[0] + cv::mean(diff)[1] + cv::mean(diff)[2], 3 * 4.0);
}

TEST_F(ImageIo, SixteenBitPngIsReadAsItsEightBitValues) {
  cv::Mat img16(40, 50, CV_16UC1);
  for (int y = 0; y < img16.rows; ++y)
    for (int x = 0; x < img16.cols; ++x) img16.at<std::uint16_t>(y, x) = std::uint16_t((x * 1300 + y * 97) % 65536);
  const auto p = (dir_ / "16.png").string();
  ASSERT_TRUE(cv::imwrite(p, img16));
  const cv::Mat gray = LoadImageGray(p);
  ASSERT_EQ(gray.type(), CV_8UC1);
  for (int y = 0; y < img16.rows; ++y)
    for (int x = 0; x < img16.cols; ++x)
      ASSERT_NEAR(gray.at<std::uint8_t>(y, x), img16.at<std::uint16_t>(y, x) / 257.0, 1.01) << x << "," << y;
}

TEST_F(ImageIo, UnsupportedPhoneFormatsAreNamed) {
  std::vector<char> gif = {'G', 'I', 'F', '8', '9', 'a', 10, 0, 10, 0, 0, 0, 0};
  ExpectError(Write("a.gif", gif), "GIF images are not supported");
  std::vector<char> heic = {0, 0, 0, 24, 'f', 't', 'y', 'p', 'h', 'e', 'i', 'c', 0, 0, 0, 0, 'm', 'i', 'f', '1'};
  ExpectError(Write("a.heic", heic), "HEIC/HEIF images are not supported");
  std::vector<char> avif = {0, 0, 0, 24, 'f', 't', 'y', 'p', 'a', 'v', 'i', 'f', 0, 0, 0, 0};
  ExpectError(Write("a.avif", avif), "AVIF images are not supported");
}

TEST_F(ImageIo, WebpSizeIsReadFromItsHeader) {
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".webp", Smooth(123, 77), bytes)) GTEST_SKIP() << "this OpenCV has no WebP encoder";
  const ImageHeader h = ReadImageHeader("a.webp", bytes.data(), bytes.size());
  EXPECT_EQ(h.format, "webp");
  EXPECT_EQ(h.width, 123);
  EXPECT_EQ(h.height, 77);
  EXPECT_EQ(DecodeImageGray("a.webp", bytes).size(), cv::Size(123, 77));
  ImageLimits small;
  small.max_pixels = 123 * 77 - 1;
  EXPECT_THROW(DecodeImageGray("a.webp", bytes, small), Error);
}

TEST_F(ImageIo, LargeJpegDecodesReducedAndMapsBack) {
  const cv::Mat big = Smooth(2000, 1500);
  std::vector<std::uint8_t> bytes;
  ASSERT_TRUE(cv::imencode(".jpg", big, bytes));
  const ReducedImage r = DecodeImageGrayReduced("big.jpg", bytes, 480);
  EXPECT_EQ(r.reduce, 4);  // 2000 / 4 = 500 >= 480, 2000 / 8 < 480
  EXPECT_EQ(r.gray.size(), cv::Size(500, 375));
  EXPECT_EQ(r.full, cv::Size(2000, 1500));
  // The reduced image is the full one area-averaged, up to JPEG loss.
  cv::Mat full_gray;
  cv::cvtColor(big, full_gray, cv::COLOR_BGR2GRAY);
  cv::Mat down;
  cv::resize(full_gray, down, r.gray.size(), 0, 0, cv::INTER_AREA);
  cv::Mat diff;
  cv::absdiff(down, r.gray, diff);
  EXPECT_LT(cv::mean(diff)[0], 3.0);
  const cv::Vec3d c = r.ToFull() * cv::Vec3d(0, 0, 1);
  EXPECT_DOUBLE_EQ(c[0], 1.5);  // reduced pixel 0 is the mean of full pixels 0..3
  // Small or non-JPEG images, or no minimum: decoded in full.
  EXPECT_EQ(DecodeImageGrayReduced("big.jpg", bytes, 0).reduce, 1);
  EXPECT_EQ(DecodeImageGrayReduced("big.jpg", bytes, 1500).reduce, 1);
  std::vector<std::uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", big, png));
  EXPECT_EQ(DecodeImageGrayReduced("big.png", png, 480).reduce, 1);
  // The limits hold for the full size even when decoding reduced.
  ImageLimits lim;
  lim.max_pixels = 2000 * 1500 - 1;
  EXPECT_THROW(DecodeImageGrayReduced("big.jpg", bytes, 480, lim), Error);
}

}  // namespace
}  // namespace mvkp
