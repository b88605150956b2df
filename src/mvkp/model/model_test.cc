#include "mvkp/model/model.h"

#include <filesystem>

#include <gtest/gtest.h>

#include "mvkp/core/crc32.h"
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

TEST(ModelFile, KeepsLevelsAndEnvelope) {
  Model m = Small();
  m.params.levels = 3;
  m.params.view_model = 2;
  m.params.max_tilt_deg = 80;
  m.locations[1].level = 2;
  m.locations[1].scale = 4.f;
  const auto bytes = SerializeModel(m);
  const Model r = DeserializeModel(bytes.data(), bytes.size(), "x");
  EXPECT_EQ(r.params.levels, 3);
  EXPECT_EQ(r.params.view_model, 2);
  EXPECT_EQ(r.params.max_tilt_deg, 80.f);
  EXPECT_EQ(r.locations[0].level, 0);
  EXPECT_EQ(r.locations[1].level, 2);
  EXPECT_EQ(r.locations[1].scale, 4.f);
  m.locations[1].level = 3;  // beyond the model's levels
  EXPECT_THROW(SerializeModel(m), Error);
}

// A version-1 file (before the training pyramid), written field by field as
// mvkp 0.x wrote it: it loads as one level of affine views.
TEST(ModelFile, ReadsVersion1Files) {
  std::vector<std::uint8_t> p;
  auto put = [&](const auto v) {
    const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
    p.insert(p.end(), b, b + sizeof(v));
  };
  put(1.0f);                       // smooth_sigma
  put(std::int32_t(32));           // patch_size
  put(std::int32_t(4));            // dims
  put(std::uint8_t(1));            // orient
  put(std::int32_t(15));           // orientation_radius
  put(2e-4f);                      // min_strength
  put(0.005f);                     // relative_threshold
  put(3.f);                        // min_distance
  put(std::int32_t(3));            // block_size
  put(std::int32_t(100));          // views
  put(std::int32_t(2));            // locations
  put(std::int32_t(20));           // clusters
  put(std::uint64_t(42));          // seed
  put(0.4f);                       // min_scale
  put(1.6f);                       // max_scale
  put(123.0);                      // train_ms
  put(std::int32_t(100));          // object_width
  put(std::int32_t(80));           // object_height
  put(std::uint32_t(2));           // locations: x, y, stability
  put(10.f), put(20.f), put(std::int32_t(50));
  put(30.f), put(40.f), put(std::int32_t(45));
  put(std::uint32_t(2));           // centres: label, dims floats
  put(std::int32_t(0)), put(1.f), put(2.f), put(3.f), put(4.f);
  put(std::int32_t(1)), put(5.f), put(6.f), put(7.f), put(8.f);
  std::vector<std::uint8_t> f = {'M', 'V', 'K', 'P', 'M', 'O', 'D', 'L'};
  auto put_f = [&](const auto v) {
    const auto* b = reinterpret_cast<const std::uint8_t*>(&v);
    f.insert(f.end(), b, b + sizeof(v));
  };
  put_f(std::uint32_t(1));
  put_f(std::uint64_t(p.size()));
  f.insert(f.end(), p.begin(), p.end());
  put_f(Crc32(p.data(), p.size()));
  const Model m = DeserializeModel(f.data(), f.size(), "old.mvkp");
  EXPECT_EQ(m.params.levels, 1);
  EXPECT_EQ(m.params.view_model, 0);
  EXPECT_EQ(m.params.views, 100);
  ASSERT_EQ(m.locations.size(), 2u);
  EXPECT_EQ(m.locations[1].x, 30.f);
  EXPECT_EQ(m.locations[1].stability, 45);
  EXPECT_EQ(m.locations[1].level, 0);
  EXPECT_EQ(m.locations[1].scale, 1.f);
  EXPECT_EQ(m.descriptors.at<float>(1, 3), 8.f);
  // Saved again it is a version-2 file with the same content.
  const auto again = SerializeModel(m);
  EXPECT_EQ(again[8], kModelFormatVersion);
  EXPECT_EQ(DeserializeModel(again.data(), again.size(), "x").locations[1].y, 40.f);
}

TEST(ModelFile, NewerVersionNamesBothVersions) {
  auto future = SerializeModel(Small());
  future[8] = 7;
  const std::string e = ErrorOf(future);
  EXPECT_NE(e.find("version 7"), std::string::npos) << e;
  EXPECT_NE(e.find("1.." + std::to_string(kModelFormatVersion)), std::string::npos) << e;
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
