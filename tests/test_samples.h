// Shared by the unit tests: loads a bundled sample image (samples/NAME) as
// 8-bit grayscale, failing the current test if it cannot be read.
// MVKP_SOURCE_DIR is defined for every test target by mvkp_add_library.
#pragma once

#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

namespace mvkp::testing {

inline cv::Mat Sample(const std::string& name) {
  cv::Mat m = cv::imread(std::string(MVKP_SOURCE_DIR) + "/samples/" + name, cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(m.empty()) << name;
  return m;
}

}  // namespace mvkp::testing
