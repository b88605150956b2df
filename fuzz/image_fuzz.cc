// Image header checks and decoders (mvkp/core/image_io.h) on arbitrary bytes:
// ReadImageHeader, then DecodeImageGray (from memory) or LoadImageColor (from
// a file), chosen by the input's last byte. Either returns an image within
// the limits or throws mvkp::Error; nothing else is allowed.
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "temp_file.h"

namespace {

// Small limits keep each run fast and show that a header cannot make the
// decoder allocate past them.
mvkp::ImageLimits Limits() {
  mvkp::ImageLimits l;
  l.min_side = 1;
  l.max_side = 1024;
  l.max_pixels = 1 << 16;
  l.max_file_bytes = 1 << 20;
  return l;
}

void Check(const cv::Mat& img, int type, const mvkp::ImageLimits& l) {
  if (img.empty() || img.type() != type || img.cols > l.max_side || img.rows > l.max_side ||
      std::int64_t(img.cols) * img.rows > l.max_pixels)
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const mvkp::ImageLimits limits = Limits();
  static mvkp::fuzz::TempFile file(".img");
  try {
    const mvkp::ImageHeader h = mvkp::ReadImageHeader("fuzz", data, size);
    if (h.width < 0 || h.height < 0) std::abort();
  } catch (const mvkp::Error&) {
  }
  try {
    if (size && data[size - 1] & 1) {
      Check(mvkp::LoadImageColor(file.Write(data, size), limits), CV_8UC3, limits);
    } else {
      Check(mvkp::DecodeImageGray("fuzz", std::vector<std::uint8_t>(data, data + size), limits), CV_8UC1, limits);
    }
  } catch (const mvkp::Error&) {
  }
  return 0;
}
