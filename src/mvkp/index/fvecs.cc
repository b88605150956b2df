#include "mvkp/index/fvecs.h"

#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <system_error>


#include "mvkp/core/atomic_file.h"
#include "mvkp/core/error.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void Fail(ErrorCode code, const std::string& path, const std::string& what) {
  throw Error(code, path + ": " + what);
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

std::uint32_t ByteSwap32(std::uint32_t v) {
  return (v >> 24) | ((v >> 8) & 0xff00u) | ((v << 8) & 0xff0000u) | (v << 24);
}

// Converts between little-endian file order and host order, in place.
void LittleEndian32(void* p, std::size_t count) {
  if constexpr (std::endian::native == std::endian::big) {
    auto* u = static_cast<unsigned char*>(p);
    for (std::size_t i = 0; i < count; ++i) {
      std::uint32_t v;
      std::memcpy(&v, u + 4 * i, 4);
      v = ByteSwap32(v);
      std::memcpy(u + 4 * i, &v, 4);
    }
  }
}

std::string Plural(std::size_t n, const char* word) {
  return std::to_string(n) + " " + word + (n == 1 ? "" : "s");
}

// "NaN" or "+inf"/"-inf", for messages.
std::string NonFiniteName(float v) { return std::isnan(v) ? "NaN" : (v > 0 ? "+inf" : "-inf"); }

}  // namespace

VectorSet ReadFvecs(const std::string& path, std::size_t max_vectors) {
  std::error_code ec;
  if (!fs::exists(path, ec)) Fail(ErrorCode::kIo, path, "no such file");
  if (fs::is_directory(path, ec)) Fail(ErrorCode::kIo, path, "is a directory, not an .fvecs file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) Fail(ErrorCode::kIo, path, "cannot read file size: " + ec.message());
  if (size == 0) Fail(ErrorCode::kIo, path, "empty file (no vectors)");
  File f(std::fopen(path.c_str(), "rb"));
  if (!f) Fail(ErrorCode::kIo, path, std::string("cannot open for reading: ") + std::strerror(errno));

  VectorSet set;
  std::uintmax_t offset = 0;
  for (std::size_t i = 0; max_vectors == 0 || i < max_vectors; ++i) {
    if (offset == size) break;
    std::int32_t d = 0;
    const std::size_t got = std::fread(&d, 1, 4, f.get());
    if (got != 4) {
      if (std::ferror(f.get())) Fail(ErrorCode::kIo, path, "read error");
      Fail(ErrorCode::kIo, path,
           "truncated: vector " + std::to_string(i) + " has " + Plural(got, "byte") +
               " of its 4-byte dimension header (file size " + std::to_string(size) +
               " is not a whole number of records)");
    }
    LittleEndian32(&d, 1);
    if (d <= 0 || d > kMaxFvecsDim)
      Fail(ErrorCode::kInvalidArgument, path,
           "vector " + std::to_string(i) + " declares dimension " + std::to_string(d) + " (must be 1.." +
               std::to_string(kMaxFvecsDim) + ")");
    if (i == 0) {
      set.dim = d;
      const std::uintmax_t record = 4 + 4 * std::uintmax_t(d);
      std::uintmax_t expect = size / record;
      if (max_vectors > 0 && expect > max_vectors) expect = max_vectors;
      set.data.reserve(std::size_t(expect) * std::size_t(d));
    } else if (d != set.dim) {
      Fail(ErrorCode::kInvalidArgument, path,
           "inconsistent dimensions: vector " + std::to_string(i) + " has dimension " + std::to_string(d) +
               ", vector 0 has " + std::to_string(set.dim));
    }
    const std::size_t base = set.data.size();
    set.data.resize(base + std::size_t(d));
    float* v = set.data.data() + base;
    const std::size_t values = std::fread(v, 4, std::size_t(d), f.get());
    if (values != std::size_t(d)) {
      if (std::ferror(f.get())) Fail(ErrorCode::kIo, path, "read error");
      Fail(ErrorCode::kIo, path,
           "truncated: vector " + std::to_string(i) + " is cut short after " + std::to_string(values) + " of " +
               std::to_string(d) + " values (file size " + std::to_string(size) +
               " is not a whole number of " + std::to_string(4 + 4 * std::uintmax_t(d)) + "-byte records)");
    }
    LittleEndian32(v, std::size_t(d));
    for (int j = 0; j < d; ++j)
      if (!std::isfinite(v[j]))
        Fail(ErrorCode::kInvalidArgument, path,
             "vector " + std::to_string(i) + " has a non-finite value (" + NonFiniteName(v[j]) + ") at component " +
                 std::to_string(j));
    offset += 4 + 4 * std::uintmax_t(d);
    ++set.n;
  }
  return set;
}

void WriteFvecs(const std::string& path, const float* data, std::size_t n, int dim) {
  Require(dim >= 1 && dim <= kMaxFvecsDim, ErrorCode::kInvalidArgument,
          path + ": cannot write dimension " + std::to_string(dim) + " (must be 1.." + std::to_string(kMaxFvecsDim) +
              ")");
  Require(n > 0, ErrorCode::kInvalidArgument, path + ": no vectors to write (an empty .fvecs file is invalid)");
  Require(data != nullptr, ErrorCode::kInvalidArgument, path + ": null data");
  for (std::size_t i = 0; i < n; ++i)
    for (int j = 0; j < dim; ++j) {
      const float v = data[i * std::size_t(dim) + j];
      if (!std::isfinite(v))
        throw Error(ErrorCode::kInvalidArgument, path + ": vector " + std::to_string(i) + " has a non-finite value (" +
                                                     NonFiniteName(v) + ") at component " + std::to_string(j));
    }

  WriteFileAtomically(path, [&](std::FILE* f) {
    std::vector<float> row(static_cast<std::size_t>(dim));
    for (std::size_t i = 0; i < n; ++i) {
      std::int32_t d = dim;
      LittleEndian32(&d, 1);
      std::memcpy(row.data(), data + i * std::size_t(dim), sizeof(float) * std::size_t(dim));
      LittleEndian32(row.data(), row.size());
      if (std::fwrite(&d, 4, 1, f) != 1 || std::fwrite(row.data(), 4, row.size(), f) != row.size()) return false;
    }
    return true;
  });
}

}  // namespace mvkp
