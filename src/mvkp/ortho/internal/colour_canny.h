// cv::Canny on a colour image with less memory. cv::Canny on 3 channels
// holds two full 3-channel 16-bit derivative images (12 bytes a pixel: 16 MB
// on a 1.3 Mpx photo, the registration's peak). The same edges come from the
// derivatives of the channel with the largest gradient at each pixel (what
// cv::Canny keeps), computed here in bands of rows and handed to the
// derivative form of cv::Canny: 4 bytes a pixel. Same bytes as cv::Canny
// (tested on photos and noise against the OpenCV in use).
#pragma once

#include <opencv2/core.hpp>

namespace mvkp::internal {

// Edges of an 8-bit BGR image: as cv::Canny(img, edges, low, high, 3, l2).
// band_rows: rows of 3-channel derivatives held at once.
void ColourCanny(const cv::Mat3b& img, cv::Mat1b* edges, double low, double high, bool l2, int band_rows = 64);

}  // namespace mvkp::internal
