// Guarded image loading.
//
// cv::imread returns an empty Mat for most failures, silently decodes truncated
// JPEGs into grey-filled images, and will try to allocate whatever a header
// declares. LoadImage checks the file before decoding: it exists, its header
// is one of the formats we read, its declared size is within limits, and its
// data is complete. Every failure throws mvkp::Error naming the file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

struct ImageLimits {
  int min_side = 16;                        // smaller images cannot hold one 32x32 patch
  int max_side = 32768;                     // per dimension, in pixels
  std::int64_t max_pixels = 100'000'000;    // width * height
  std::int64_t max_file_bytes = 1LL << 30;  // 1 GiB
};

// Dimensions read from a file's header without decoding it.
struct ImageHeader {
  // "png", "jpeg", "pnm", "bmp", "tiff", "webp", "unknown", or a format named
  // so that the error can say so: "gif", "heif" (HEIC), "avif"
  std::string format;
  int width = 0;
  int height = 0;
  bool complete = true;     // false when the data is shorter than the header implies
  std::string incomplete;   // why, when !complete
};

// Reads the header of an in-memory encoded image; width/height stay 0 when the
// format does not say them up front. Throws Error(kBadImage) on a damaged header.
ImageHeader ReadImageHeader(const std::string& name, const std::uint8_t* data, std::size_t size);

// Loads an image as 8-bit grayscale (CV_8UC1).
cv::Mat LoadImageGray(const std::string& path, const ImageLimits& limits = {});

// Loads an image as 8-bit BGR (CV_8UC3), for drawing.
cv::Mat LoadImageColor(const std::string& path, const ImageLimits& limits = {});

// The same checks and decoding for bytes in memory (e.g. an HTTP body);
// `name` stands for the file in error messages.
cv::Mat DecodeImageGray(const std::string& name, const std::vector<std::uint8_t>& bytes, const ImageLimits& limits = {});

// A photo decoded for a working size. JPEGs are decoded at 1/2, 1/4 or 1/8
// of their size (libjpeg's DCT scaling: a fraction of the time and memory)
// while the longer side stays at least `min_side`; other formats, and
// min_side <= 0, decode in full. The limits apply to the full size.
struct ReducedImage {
  cv::Mat gray;         // CV_8UC1
  int reduce = 1;       // 1, 2, 4 or 8
  cv::Size full;        // the image's own size
  // Maps gray's pixel coordinates to the full image's: reduced pixel x
  // covers full pixels [x * reduce, (x + 1) * reduce).
  cv::Matx33d ToFull() const {
    const double r = reduce, c = (r - 1) / 2;
    return {r, 0, c, 0, r, c, 0, 0, 1};
  }
};
ReducedImage DecodeImageGrayReduced(const std::string& name, const std::vector<std::uint8_t>& bytes, int min_side,
                                    const ImageLimits& limits = {});

// Checks an in-memory image (e.g. from numpy or a camera) against the limits.
void CheckImage(const cv::Mat& image, const std::string& name, const ImageLimits& limits = {});

// Writes an image; throws Error(kIo) when the path cannot be written.
void SaveImage(const std::string& path, const cv::Mat& image);

}  // namespace mvkp
