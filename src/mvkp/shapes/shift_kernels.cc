#include "mvkp/shapes/internal/shift_kernels.h"

#include "mvkp/core/internal/cpu.h"
#include "shift_kernels_impl.h"

namespace mvkp::internal {

void ShiftSumsScalar(const float* a, int lda, const float* bt, int ldb, int n, int B, double* sum, float* row) {
  impl::ShiftSums(a, lda, bt, ldb, n, B, sum, row);
}

ShiftSumsFn BestShiftSums() {
  return CpuHasAvx2() ? ShiftSumsAvx2 : ShiftSumsScalar;
}

}  // namespace mvkp::internal
