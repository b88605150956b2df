// The inner loop of ShiftCosts (the shape-context cost of every circular
// shift), in a scalar build and an AVX2 build of the same source
// (shift_kernels_avx2.cc, -mavx2 -ffp-contract=off) chosen at run time. The
// loops are element-wise (no reordered sums), so both builds give
// bit-identical costs (tested).
#pragma once

namespace mvkp::internal {

// a: n x B rows (row step lda floats); bt: B x n (row step ldb floats), b
// transposed. sum[k] = sum over j of <a_j, b_((j + k) mod n)>, accumulated
// in j order; row: scratch of n floats.
using ShiftSumsFn = void (*)(const float* a, int lda, const float* bt, int ldb, int n, int B, double* sum, float* row);
void ShiftSumsScalar(const float* a, int lda, const float* bt, int ldb, int n, int B, double* sum, float* row);
void ShiftSumsAvx2(const float* a, int lda, const float* bt, int ldb, int n, int B, double* sum, float* row);
ShiftSumsFn BestShiftSums();

}  // namespace mvkp::internal
