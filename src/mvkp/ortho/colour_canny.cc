#include "mvkp/ortho/internal/colour_canny.h"

#include <algorithm>
#include <cstdlib>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp::internal {

void ColourCanny(const cv::Mat3b& img, cv::Mat1b* edges, double low, double high, bool l2, int band_rows) {
  Require(!img.empty() && band_rows >= 1, ErrorCode::kInvalidArgument, "ColourCanny: need an image and band_rows >= 1");
  const int rows = img.rows, cols = img.cols;
  cv::Mat1s dx(rows, cols), dy(rows, cols);
  cv::Mat bx, by;  // one band's 3-channel derivatives
  for (int y0 = 0; y0 < rows; y0 += band_rows) {
    const int y1 = std::min(rows, y0 + band_rows);
    // a band of a larger image: the filter reads the rows around it from the
    // image itself and replicates only at the image's own border, as a
    // whole-image Sobel does
    const cv::Mat band = img.rowRange(y0, y1);
    cv::Sobel(band, bx, CV_16S, 1, 0, 3, 1, 0, cv::BORDER_REPLICATE);
    cv::Sobel(band, by, CV_16S, 0, 1, 3, 1, 0, cv::BORDER_REPLICATE);
    for (int y = 0; y < y1 - y0; ++y) {
      const short* gx = bx.ptr<short>(y);
      const short* gy = by.ptr<short>(y);
      short* ox = dx.ptr<short>(y0 + y);
      short* oy = dy.ptr<short>(y0 + y);
      for (int x = 0; x < cols; ++x, gx += 3, gy += 3) {
        // the channel of the largest magnitude, the first one on ties
        int best = 0, mag = 0;
        for (int c = 0; c < 3; ++c) {
          const int a = gx[c], b = gy[c];
          const int m = l2 ? a * a + b * b : std::abs(a) + std::abs(b);
          if (c == 0 || m > mag) best = c, mag = m;
        }
        ox[x] = gx[best], oy[x] = gy[best];
      }
    }
  }
  cv::Canny(dx, dy, *edges, low, high, l2);
}

}  // namespace mvkp::internal
