// Plain loops shared by the scalar reference (code_kernels.cc) and the AVX2
// translation unit (code_kernels_avx2.cc), which compiles the same source
// with -mavx2 -mpopcnt. Internal linkage on purpose: each file gets its own
// copy built with its own flags, so the linker can never hand the scalar path
// an AVX2-compiled body.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>

namespace mvkp::augment_internal {
namespace {

// out[r] = |{j : q[j] != rows[r * dim + j]}|.
inline void CountDiffRowsLoop(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                              std::int32_t* out) {
  for (std::size_t r = 0; r < n; ++r) {
    const std::uint8_t* x = rows + r * std::size_t(dim);
    std::int32_t s = 0;
    for (int j = 0; j < dim; ++j) s += q[j] != x[j];
    out[r] = s;
  }
}

// out[r] = sum_w popcount(q[w] ^ rows[r * words + w]).
inline void XorPopcountRowsLoop(const std::uint64_t* q, const std::uint64_t* rows, std::size_t n, int words,
                                std::int32_t* out) {
  for (std::size_t r = 0; r < n; ++r) {
    const std::uint64_t* x = rows + r * std::size_t(words);
    std::int32_t s = 0;
    for (int w = 0; w < words; ++w) s += std::popcount(q[w] ^ x[w]);
    out[r] = s;
  }
}

}  // namespace
}  // namespace mvkp::augment_internal
