// Compiled with -mavx2 -mfma (see CMakeLists.txt); reached only through
// BestL2Blocks8() after a run-time CPU check.
#include <immintrin.h>

#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp::internal {

void L2Blocks8Avx2(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out) {
  for (std::size_t b = 0; b < nblocks; ++b) {
    const float* blk = blocks + b * std::size_t(dim) * kLanes;
    __m256 acc0 = _mm256_setzero_ps(), acc1 = _mm256_setzero_ps();
    int d = 0;
    for (; d + 1 < dim; d += 2) {
      const __m256 d0 = _mm256_sub_ps(_mm256_loadu_ps(blk + d * kLanes), _mm256_set1_ps(q[d]));
      const __m256 d1 = _mm256_sub_ps(_mm256_loadu_ps(blk + (d + 1) * kLanes), _mm256_set1_ps(q[d + 1]));
      acc0 = _mm256_fmadd_ps(d0, d0, acc0);
      acc1 = _mm256_fmadd_ps(d1, d1, acc1);
    }
    if (d < dim) {
      const __m256 d0 = _mm256_sub_ps(_mm256_loadu_ps(blk + d * kLanes), _mm256_set1_ps(q[d]));
      acc0 = _mm256_fmadd_ps(d0, d0, acc0);
    }
    _mm256_storeu_ps(out + b * kLanes, _mm256_add_ps(acc0, acc1));
  }
}

}  // namespace mvkp::internal
