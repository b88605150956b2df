// AVX2 build of ShiftSums (compiled with -mavx2 -ffp-contract=off; see
// CMakeLists.txt): the same source as the scalar build, vectorised eight
// floats wide by the compiler; reached only through BestShiftSums.
#include "mvkp/shapes/internal/shift_kernels.h"

#include "shift_kernels_impl.h"

namespace mvkp::internal {

void ShiftSumsAvx2(const float* a, int lda, const float* bt, int ldb, int n, int B, double* sum, float* row) {
  impl::ShiftSums(a, lda, bt, ldb, n, B, sum, row);
}

}  // namespace mvkp::internal
