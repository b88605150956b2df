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
bool DecodeJpeg(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error);
bool DecodePng(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error);
// P2, P3, P5, P6 (other PNM kinds return false with an empty error: not handled).
bool DecodePnm(const std::uint8_t* data, std::size_t size, bool gray, cv::Mat& out, std::string& error);

}  // namespace mvkp::internal
