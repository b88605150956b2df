// Compiled with -mavx2 -mfma (see CMakeLists.txt); reached only through
// BestL2Blocks8() after a run-time CPU check.
#include <immintrin.h>

#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp::internal {

void L2Blocks8Avx2(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out) {
  for (std::size_t b = 0; b < nblocks; ++b) {
    const float* blk = blocks + b * std::size_t(dim) * kLanes;
    __m256 acc = _mm256_setzero_ps();
    for (int d = 0; d < dim; ++d) {
      const __m256 x = _mm256_sub_ps(_mm256_loadu_ps(blk + d * kLanes), _mm256_set1_ps(q[d]));
      acc = _mm256_fmadd_ps(x, x, acc);
    }
    _mm256_storeu_ps(out + b * kLanes, acc);
  }
}

void TwoDistinctAvx2(const float* blocks, const std::int32_t* labels, std::size_t nblocks, const float* q, int dim,
                     std::int32_t first_id, TopTwo& t) {
  // Full distances without early exits: at these dimensions a mispredicted
  // "abandon this block" branch costs more than finishing the block. The
  // only branch, "some lane beats the bound", is rarely taken. Accumulation
  // is sequential in dimension order with FMA, exactly as the scalar
  // reference, so both give bit-identical distances.
  float bound_s = t.Bound();
  __m256 bound = _mm256_set1_ps(bound_s);
  for (std::size_t b = 0; b < nblocks; ++b) {
    const float* blk = blocks + b * std::size_t(dim) * kLanes;
    __m256 acc = _mm256_setzero_ps();
    for (int d = 0; d < dim; ++d) {
      const __m256 x = _mm256_sub_ps(_mm256_loadu_ps(blk + d * kLanes), _mm256_set1_ps(q[d]));
      acc = _mm256_fmadd_ps(x, x, acc);
    }
    int mask = _mm256_movemask_ps(_mm256_cmp_ps(acc, bound, _CMP_LT_OQ));
    if (__builtin_expect(mask == 0, 1)) continue;
    alignas(32) float dist[kLanes];
    _mm256_store_ps(dist, acc);
    const std::int32_t* lab = labels + b * kLanes;
    while (mask) {
      const int l = __builtin_ctz(unsigned(mask));
      mask &= mask - 1;
      TopTwoOffer(t, dist[l], first_id + std::int32_t(b * kLanes + l), lab[l]);
    }
    bound_s = t.Bound();
    bound = _mm256_set1_ps(bound_s);
  }
}

}  // namespace mvkp::internal
