// Distance kernels between ordinal codes of bytes. Internal to mvkp_augment.
#pragma once

#include <cstddef>
#include <cstdint>

namespace mvkp::augment_internal {

// out[r] = sum_j (q[j] - rows[r * dim + j])^2 for n rows of dim bytes
// (dim <= 255, so the sums fit int32). Scalar reference.
void SumSqDiffRowsScalar(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                         std::int32_t* out);
// The same with AVX2; call only when CpuHasAvx2(). Integer sums: equal to the
// scalar reference exactly.
void SumSqDiffRowsAvx2(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                       std::int32_t* out);

using SumSqDiffRowsFn = void (*)(const std::uint8_t*, const std::uint8_t*, std::size_t, int, std::int32_t*);
// AVX2 when the CPU has it, else the scalar reference; chosen once (as the
// other Best* functions).
SumSqDiffRowsFn BestSumSqDiffRows();

// out[r] = |{j : q[j] != rows[r * dim + j]}| for n rows of dim bytes.
void CountDiffRowsScalar(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                         std::int32_t* out);
void CountDiffRowsAvx2(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                       std::int32_t* out);
using CountDiffRowsFn = SumSqDiffRowsFn;
CountDiffRowsFn BestCountDiffRows();

// out[r] = sum_w popcount(q[w] ^ rows[r * words + w]) for n rows of `words`
// 64-bit words. Scalar reference (std::popcount) and the same code compiled
// with hardware popcnt.
void XorPopcountRowsScalar(const std::uint64_t* q, const std::uint64_t* rows, std::size_t n, int words,
                           std::int32_t* out);
void XorPopcountRowsAvx2(const std::uint64_t* q, const std::uint64_t* rows, std::size_t n, int words,
                         std::int32_t* out);

using XorPopcountRowsFn = void (*)(const std::uint64_t*, const std::uint64_t*, std::size_t, int, std::int32_t*);
XorPopcountRowsFn BestXorPopcountRows();

bool CpuHasAvx2();

}  // namespace mvkp::augment_internal
