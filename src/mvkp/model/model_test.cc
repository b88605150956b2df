#include "mvkp/model/model.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

Model Small() {
  Model m;
  m.object_width = 100;
  m.object_height = 80;
  m.params.dims = 4;
  m.locations = {{10, 20, 50}, {30, 40, 45}};
  m.descriptors = (cv::Mat_<float>(3, 4) << 1, 2, 3, 4, 5, 6, 7, 8, -1, -2, -3, -4);
  m.labels = {0, 0, 1};
  return m;
}

std::string ErrorOf(const std::vector<std::uint8_t>& b) {
  try {
    DeserializeModel(b.data(), b.size(), "m.mvkp");
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kBadModel);
    return e.what();
  }
  return "";
}

TEST(ModelFile, RoundTrips) {
  const Model m = Small();
  const auto bytes = SerializeModel(m);
  const Model r = DeserializeModel(bytes.data(), bytes.size(), "x");
  EXPECT_EQ(r.object_width, 100);
  EXPECT_EQ(r.labels, m.labels);
  ASSERT_EQ(r.locations.size(), 2u);
  EXPECT_EQ(r.locations[1].stability, 45);
  EXPECT_EQ(cv::norm(r.descriptors, m.descriptors, cv::NORM_INF), 0.0);
  const auto path = (std::filesystem::temp_directory_path() / "mvkp_model_test.mvkp").string();
  SaveModel(m, path);
  EXPECT_EQ(LoadModel(path).descriptors.rows, 3);
  std::filesystem::remove(path);
}

TEST(ModelFile, RejectsDamage) {
  const auto good = SerializeModel(Small());
  EXPECT_NE(ErrorOf({good.begin(), good.begin() + 5}).find("bad magic"), std::string::npos);
  EXPECT_NE(ErrorOf({good.begin(), good.begin() + 16}).find("truncated"), std::string::npos);
  for (std::size_t cut : {good.size() - 1, good.size() - 10, std::size_t(30)})
    EXPECT_NE(ErrorOf({good.begin(), good.begin() + long(cut)}).find("truncated"), std::string::npos) << cut;
  for (std::size_t pos = 20; pos < good.size() - 4; pos += 7) {
    auto bad = good;
    bad[pos] ^= 0x5A;
    EXPECT_NE(ErrorOf(bad).find("checksum"), std::string::npos) << pos;
  }
  auto future = good;
  future[8] = 99;
  EXPECT_NE(ErrorOf(future).find("newer"), std::string::npos);
  auto trailing = good;
  trailing.push_back(0);
  EXPECT_NE(ErrorOf(trailing).find("trailing"), std::string::npos);
}

TEST(ModelFile, MissingFileIsAnIoError) {
  try {
    LoadModel("/nonexistent/m.mvkp");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kIo);
  }
}

TEST(ModelFile, ValidateCatchesBadLabels) {
  Model m = Small();
  m.labels[2] = 7;
  EXPECT_THROW(SerializeModel(m), Error);
}

}  // namespace
}  // namespace mvkp
