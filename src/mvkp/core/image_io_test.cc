#include "mvkp/core/image_io.h"

#include <filesystem>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

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

}  // namespace
}  // namespace mvkp
