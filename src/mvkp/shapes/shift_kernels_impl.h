// The loop body shared by the scalar and AVX2 builds of ShiftSums (see
// internal/shift_kernels.h); included by one .cc file per build.
#pragma once

#include <algorithm>

namespace mvkp::internal::impl {

inline void ShiftSums(const float* a, int lda, const float* bt, int ldb, int n, int B, double* sum, float* row) {
  std::fill(sum, sum + n, 0.0);
  // s(j, i) = <a_j, b_i>, row by row as axpy over the (sparse) bins of a_j;
  // sum[k] accumulates the diagonal i = (j + k) % n.
  for (int j = 0; j < n; ++j) {
    std::fill(row, row + n, 0.0f);
    const float* aj = a + static_cast<long>(j) * lda;
    for (int k = 0; k < B; ++k) {
      const float w = aj[k];
      if (w == 0.0f) continue;
      const float* bk = bt + static_cast<long>(k) * ldb;
      for (int i = 0; i < n; ++i) row[i] += w * bk[i];
    }
    for (int k = 0, i = j; k < n; ++k) {
      sum[k] += row[i];
      if (++i == n) i = 0;
    }
  }
}

}  // namespace mvkp::internal::impl
