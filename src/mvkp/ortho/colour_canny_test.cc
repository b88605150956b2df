// ColourCanny must give cv::Canny's edges on colour images, byte for byte
// (the photo segmentation's answers may not change), with less memory.
#include "mvkp/ortho/internal/colour_canny.h"

#include <filesystem>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp::internal {
namespace {

// Flat rectangles (grey ones too: equal gradients in every channel, so the
// first-channel rule on ties matters), blurred a little, with noise.
cv::Mat3b Blocks(std::uint64_t seed, int w, int h) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> U(0, 255);
  cv::Mat3b img(h, w, cv::Vec3b(U(rng), U(rng), U(rng)));
  for (int i = 0; i < 40; ++i) {
    const int x = U(rng) * w / 256, y = U(rng) * h / 256, bw = 3 + U(rng) * w / 512, bh = 3 + U(rng) * h / 512;
    const int v = U(rng);
    const cv::Scalar c = i % 3 == 0 ? cv::Scalar(v, v, v) : cv::Scalar(U(rng), U(rng), U(rng));
    cv::rectangle(img, cv::Rect(x, y, bw, bh), c, cv::FILLED);
  }
  if (seed % 2) cv::GaussianBlur(img, img, cv::Size(), 0.8);
  cv::Mat3b noise(h, w);
  cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(double(seed % 3) * 2));
  cv::add(img, noise, img);
  return img;
}

void ExpectSameEdges(const cv::Mat3b& img, const std::string& what) {
  for (bool l2 : {true, false})
    for (int band : {1, 7, 64, 100000}) {
      const double low = l2 ? 40 : 60, high = l2 ? 100 : 150;
      cv::Mat want, got;
      cv::Canny(img, want, low, high, 3, l2);
      cv::Mat1b edges;
      ColourCanny(img, &edges, low, high, l2, band);
      ASSERT_EQ(edges.size(), want.size());
      EXPECT_EQ(cv::countNonZero(edges != want), 0) << what << " l2 " << l2 << " band " << band;
      EXPECT_GT(cv::countNonZero(want), 0) << what;  // there were edges to compare
    }
}

TEST(ColourCanny, SameEdgesAsOpenCV) {
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const int w = 97 + int(seed) * 31, h = 65 + int(seed) * 17;  // rows not a multiple of the bands
    ExpectSameEdges(Blocks(seed, w, h), "blocks " + std::to_string(seed));
  }
  // a real photo and a real orthophoto, when the shared data is there
  for (const char* rel : {"/oxford/graf/img1.ppm", "/aerial/montpellier/ortho_rgb_20cm.tif"}) {
    const std::string path = std::string(MVKP_SOURCE_DIR) + "/../shared/data" + rel;
    if (!std::filesystem::exists(path)) continue;
    const cv::Mat img = cv::imread(path, cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty()) << path;
    ExpectSameEdges(img, path);
  }
  // an image of one row and one column
  ExpectSameEdges(Blocks(7, 1, 40), "one column");
}

TEST(ColourCanny, RejectsBadInput) {
  cv::Mat1b e;
  EXPECT_THROW(ColourCanny(cv::Mat3b(), &e, 10, 20, true), Error);
  EXPECT_THROW(ColourCanny(cv::Mat3b(4, 4), &e, 10, 20, true, 0), Error);
}

}  // namespace
}  // namespace mvkp::internal
