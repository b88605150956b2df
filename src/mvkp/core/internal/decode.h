// Strict decoders for the common formats. cv::imdecode lets libjpeg and
// libpng print to stderr and accepts a JPEG whose data ends early (it fills
// the rest with grey); these decoders turn any such problem into an error
// string instead. Internal to mvkp_core.
#pragma once

#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

namespace mvkp::internal {

// Each returns true and sets `out` (CV_8UC1 if gray, else CV_8UC3 BGR), or
// returns false and sets `error`.
// JPEG: YCbCr, grayscale, RGB, CMYK and YCCK (Adobe's inverted CMYK, as
// phones' editors and print workflows write it) are read. `reduce` (1, 2, 4
// or 8) decodes at that fraction of the size with libjpeg's DCT scaling,
// which skips most of the work for a photo far larger than needed.
bool DecodeJpeg(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error,
                int reduce = 1);
// PNG: any bit depth and colour type; 16-bit samples without a gamma chunk
// are taken as sRGB (as cameras and editors write them), not linear.
bool DecodePng(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error);
// P2, P3, P5, P6 (other PNM kinds return false with an empty error: not handled).
bool DecodePnm(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error);

}  // namespace mvkp::internal
