// .fvecs vector files (the TEXMEX / SIFT1M format).
//
// A file is a sequence of records, one per vector: an int32 dimension d, then
// d float32 values, all little-endian. Every record of a file has the same d.
// Used to feed benchmarks (bench/) with fixed databases and query sets.
//
// ReadFvecs checks everything it reads and throws mvkp::Error naming the file
// and the problem:
//   kIo              missing or unreadable file, empty file, truncated file
//                    (a record cut short, so the size is not a whole number
//                    of records)
//   kInvalidArgument a dimension <= 0 or > kMaxFvecsDim, a dimension that
//                    differs from the first record's, a NaN or infinite value
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace mvkp {

inline constexpr int kMaxFvecsDim = 65536;

struct VectorSet {
  int dim = 0;
  std::size_t n = 0;
  std::vector<float> data;  // n x dim, row-major
};

// Reads the first max_vectors vectors (0 = all). With max_vectors > 0 only
// those records are read and checked, and a shorter file yields fewer vectors.
VectorSet ReadFvecs(const std::string& path, std::size_t max_vectors = 0);

// Writes n vectors of dim floats (row-major) to path, atomically: the data go
// to a temporary file beside it, which is renamed over path once complete.
// Throws Error(kInvalidArgument) for n == 0, a dimension out of range or a
// non-finite value (files ReadFvecs would reject), Error(kIo) when the file
// cannot be written.
void WriteFvecs(const std::string& path, const float* data, std::size_t n, int dim);

}  // namespace mvkp
