#include "mvkp/shapes/internal/shift_kernels.h"

#include "shift_kernels_impl.h"

namespace mvkp::internal {

void ShiftSumsScalar(const float* a, int lda, const float* bt, int ldb, int n, int B, double* sum, float* row) {
  impl::ShiftSums(a, lda, bt, ldb, n, B, sum, row);
}

ShiftSumsFn BestShiftSums() {
  static const ShiftSumsFn fn = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") ? ShiftSumsAvx2 : ShiftSumsScalar;
  }();
  return fn;
}

}  // namespace mvkp::internal
