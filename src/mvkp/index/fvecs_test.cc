#include "mvkp/index/fvecs.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;

class Fvecs : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mvkp_fvecs_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  // Little-endian bytes of a record: int32 d, then the values.
  static void Append(std::vector<char>& out, std::int32_t d, const std::vector<float>& values) {
    const auto* p = reinterpret_cast<const char*>(&d);
    out.insert(out.end(), p, p + 4);
    for (float v : values) {
      const auto* q = reinterpret_cast<const char*>(&v);
      out.insert(out.end(), q, q + 4);
    }
  }
  std::string Write(const std::string& name, const std::vector<char>& bytes) {
    const auto p = Path(name);
    std::ofstream(p, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
    return p;
  }
  // Expects ReadFvecs(path) to throw `code` with a message naming the file and containing `what`.
  static void ExpectError(const std::string& path, ErrorCode code, const std::string& what) {
    try {
      ReadFvecs(path);
      FAIL() << "no error for " << path;
    } catch (const Error& e) {
      EXPECT_EQ(int(e.code()), int(code)) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }

  fs::path dir_;
};

TEST_F(Fvecs, RoundTrip) {
  std::mt19937 rng(7);
  std::normal_distribution<float> g;
  for (int dim : {1, 3, 20, 128}) {
    const std::size_t n = 37;
    std::vector<float> data(n * dim);
    for (auto& v : data) v = g(rng);
    data[0] = std::numeric_limits<float>::max();
    data[1 % data.size()] = -0.f;
    const auto p = Path("rt.fvecs");
    WriteFvecs(p, data.data(), n, dim);
    EXPECT_EQ(fs::file_size(p), n * (4 + 4 * std::size_t(dim)));
    const VectorSet s = ReadFvecs(p);
    EXPECT_EQ(s.dim, dim);
    EXPECT_EQ(s.n, n);
    ASSERT_EQ(s.data.size(), data.size());
    EXPECT_EQ(std::memcmp(s.data.data(), data.data(), data.size() * sizeof(float)), 0);

    const VectorSet head = ReadFvecs(p, 5);
    EXPECT_EQ(head.n, 5u);
    EXPECT_EQ(head.dim, dim);
    EXPECT_EQ(std::vector<float>(data.begin(), data.begin() + 5 * dim), head.data);
    EXPECT_EQ(ReadFvecs(p, 1000).n, n);  // asking for more than the file holds
  }
}

TEST_F(Fvecs, ByteLayoutIsLittleEndianDimensionThenFloats) {
  const float v[2] = {1.5f, -2.f};
  const auto p = Path("layout.fvecs");
  WriteFvecs(p, v, 1, 2);
  std::ifstream in(p, std::ios::binary);
  const std::vector<unsigned char> bytes{std::istreambuf_iterator<char>(in), {}};
  const std::vector<unsigned char> expect = {2, 0, 0, 0, 0x00, 0x00, 0xc0, 0x3f, 0x00, 0x00, 0x00, 0xc0};
  EXPECT_EQ(bytes, expect);
}

TEST_F(Fvecs, WriteIsAtomicAndReplacesExistingFile) {
  const auto p = Path("a.fvecs");
  const std::vector<float> one(4, 1.f), two(8, 2.f);
  WriteFvecs(p, one.data(), 1, 4);
  WriteFvecs(p, two.data(), 2, 4);
  EXPECT_EQ(ReadFvecs(p).data, two);
  for (const auto& e : fs::directory_iterator(dir_))  // no temporary left behind
    EXPECT_EQ(e.path().filename().string(), "a.fvecs");
}

TEST_F(Fvecs, WriteErrorsLeaveNoFile) {
  const std::vector<float> v(4, 1.f);
  const auto p = Path("no_dir/x.fvecs");
  try {
    WriteFvecs(p, v.data(), 1, 4);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kIo);
    EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
  }
  const auto q = Path("bad.fvecs");
  EXPECT_THROW(WriteFvecs(q, v.data(), 0, 4), Error);
  EXPECT_THROW(WriteFvecs(q, v.data(), 1, 0), Error);
  EXPECT_THROW(WriteFvecs(q, v.data(), 1, kMaxFvecsDim + 1), Error);
  std::vector<float> nan = v;
  nan[2] = std::nanf("");
  try {
    WriteFvecs(q, nan.data(), 1, 4);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("vector 0"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(q));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 0);
}

TEST_F(Fvecs, MissingFile) { ExpectError(Path("nope.fvecs"), ErrorCode::kIo, "no such file"); }

TEST_F(Fvecs, Directory) { ExpectError(dir_.string(), ErrorCode::kIo, "directory"); }

TEST_F(Fvecs, EmptyFile) { ExpectError(Write("empty.fvecs", {}), ErrorCode::kIo, "empty file"); }

TEST_F(Fvecs, TruncatedInsideValues) {
  std::vector<char> b;
  Append(b, 4, {1, 2, 3, 4});
  Append(b, 4, {5, 6, 7, 8});
  b.resize(b.size() - 6);  // second vector keeps 2 of its 4 values, plus half a float
  ExpectError(Write("cut.fvecs", b), ErrorCode::kIo, "truncated: vector 1 is cut short after 2 of 4 values");
}

TEST_F(Fvecs, TruncatedInsideHeader) {
  std::vector<char> b;
  Append(b, 2, {1, 2});
  b.push_back(2);  // one stray byte: size 13 is not a multiple of the 12-byte record
  ExpectError(Write("hdr.fvecs", b), ErrorCode::kIo, "truncated: vector 1 has 1 byte");
  ExpectError(Write("tiny.fvecs", {1, 0}), ErrorCode::kIo, "truncated: vector 0 has 2 bytes");
}

TEST_F(Fvecs, RecordWithoutValues) {
  std::vector<char> b;
  Append(b, 3, {});
  ExpectError(Write("novalues.fvecs", b), ErrorCode::kIo, "cut short after 0 of 3 values");
}

TEST_F(Fvecs, InconsistentDimensions) {
  std::vector<char> b;
  Append(b, 3, {1, 2, 3});
  Append(b, 3, {1, 2, 3});
  Append(b, 2, {1, 2});
  ExpectError(Write("mixed.fvecs", b), ErrorCode::kInvalidArgument,
              "inconsistent dimensions: vector 2 has dimension 2, vector 0 has 3");
}

TEST_F(Fvecs, DimensionOutOfRange) {
  for (std::int32_t d : {0, -1, kMaxFvecsDim + 1, std::numeric_limits<std::int32_t>::max()}) {
    std::vector<char> b;
    Append(b, d, {1, 2, 3, 4});
    ExpectError(Write("dim.fvecs", b), ErrorCode::kInvalidArgument,
                "vector 0 declares dimension " + std::to_string(d) + " (must be 1..65536)");
  }
  std::vector<char> b;  // a bad dimension later in the file names its vector
  Append(b, 1, {1});
  Append(b, -5, {});
  ExpectError(Write("dim2.fvecs", b), ErrorCode::kInvalidArgument, "vector 1 declares dimension -5");
}

TEST_F(Fvecs, MaxDimensionIsAccepted) {
  std::vector<float> v(kMaxFvecsDim, 0.25f);
  const auto p = Path("big.fvecs");
  WriteFvecs(p, v.data(), 1, kMaxFvecsDim);
  const VectorSet s = ReadFvecs(p);
  EXPECT_EQ(s.dim, kMaxFvecsDim);
  EXPECT_EQ(s.n, 1u);
}

TEST_F(Fvecs, NonFiniteValuesNameTheVector) {
  const float inf = std::numeric_limits<float>::infinity();
  struct Case {
    float bad;
    const char* name;
  };
  for (const Case& c : {Case{std::nanf(""), "NaN"}, Case{inf, "+inf"}, Case{-inf, "-inf"}}) {
    std::vector<char> b;
    Append(b, 3, {1, 2, 3});
    Append(b, 3, {4, 5, 6});
    Append(b, 3, {7, c.bad, 9});
    ExpectError(Write("nan.fvecs", b), ErrorCode::kInvalidArgument,
                std::string("vector 2 has a non-finite value (") + c.name + ") at component 1");
  }
}

TEST_F(Fvecs, PrefixReadStopsBeforeDamage) {
  std::vector<char> b;
  Append(b, 2, {1, 2});
  Append(b, 2, {3, 4});
  Append(b, 2, {5, std::nanf("")});
  const auto p = Write("prefix.fvecs", b);
  const VectorSet s = ReadFvecs(p, 2);
  EXPECT_EQ(s.n, 2u);
  EXPECT_EQ(s.data, (std::vector<float>{1, 2, 3, 4}));
  EXPECT_THROW(ReadFvecs(p, 3), Error);
}

}  // namespace
}  // namespace mvkp
