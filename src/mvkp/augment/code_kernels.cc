#include "mvkp/augment/internal/code_kernels.h"
#include "mvkp/augment/internal/code_loops.h"

#include <bit>

namespace mvkp::augment_internal {

void SumSqDiffRowsScalar(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                         std::int32_t* out) {
  for (std::size_t r = 0; r < n; ++r) {
    const std::uint8_t* x = rows + r * std::size_t(dim);
    std::int32_t s = 0;
    for (int j = 0; j < dim; ++j) {
      const std::int32_t d = std::int32_t(q[j]) - std::int32_t(x[j]);
      s += d * d;
    }
    out[r] = s;
  }
}

void CountDiffRowsScalar(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                       std::int32_t* out) {
  CountDiffRowsLoop(q, rows, n, dim, out);
}

void XorPopcountRowsScalar(const std::uint64_t* q, const std::uint64_t* rows, std::size_t n, int words,
                           std::int32_t* out) {
  XorPopcountRowsLoop(q, rows, n, words, out);
}

bool CpuHasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
  }();
  return has;
}

SumSqDiffRowsFn BestSumSqDiffRows() {
  static const SumSqDiffRowsFn fn = CpuHasAvx2() ? &SumSqDiffRowsAvx2 : &SumSqDiffRowsScalar;
  return fn;
}

CountDiffRowsFn BestCountDiffRows() {
  static const CountDiffRowsFn fn = CpuHasAvx2() ? &CountDiffRowsAvx2 : &CountDiffRowsScalar;
  return fn;
}

XorPopcountRowsFn BestXorPopcountRows() {
  static const XorPopcountRowsFn fn = CpuHasAvx2() ? &XorPopcountRowsAvx2 : &XorPopcountRowsScalar;
  return fn;
}

}  // namespace mvkp::augment_internal
